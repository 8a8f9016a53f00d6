#include "apps/quality_plot.h"

namespace raynode::apps {

std::string_view quality_plot_script() {
  static constexpr std::string_view kScript = R"PY(# Written by `raynode bench quality`: render time against image error,
# with the Pareto front. Usage: python3 THIS.py PREFIX.csv PREFIX.png TITLE SUBTITLE
import csv, math, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

csv_path, png_path, title, subtitle = sys.argv[1:5]
rows = list(csv.DictReader(open(csv_path)))
for r in rows:
    r["time_s"] = float(r["time_s"]); r["rmse"] = float(r["rmse"])
    r["on_front"] = r["on_front"] == "1"; r["is_default"] = r["is_default"] == "1"
positive = [r["rmse"] for r in rows if r["rmse"] > 0]
floor = (min(positive) / 3.0) if positive else 1e-6
def y_of(r):  # a zero error cannot sit on a log axis: draw it at a floor, as a triangle
    return r["rmse"] if r["rmse"] > 0 else floor

def label(r):
    return "d{} w{:g} t{} s{} {}".format(r["max_depth"], float(r["min_weight"]), r["tessellate"], r["spp"],
                                         r["accel"])

fig, ax = plt.subplots(figsize=(10, 7))
single = ["max-depth", "min-weight", "tessellate", "spp", "accel"]
colours = dict(zip(single, ["tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown"]))
marker = {"grid": "o", "embree": "s"}
shown = set()
for r in rows:
    if r["is_default"]:
        continue
    v = r["varied"]
    c = colours.get(v, "0.6")
    name = ("varied: " + v) if v in colours else "two or more knobs varied"
    m = marker.get(r["accel"], "o") if r["rmse"] > 0 else "v"
    ax.scatter(r["time_s"], y_of(r), s=40 if v in colours else 22, c=c, marker=m, alpha=0.85,
               zorder=4 if v in colours else 3,
               edgecolors="none", label=None if name in shown else name)
    shown.add(name)
front = sorted([r for r in rows if r["on_front"]], key=lambda r: (r["time_s"], r["rmse"]))
if front:
    xs = [r["time_s"] for r in front]; ys = [y_of(r) for r in front]
    ax.step(xs, ys, where="post", color="crimson", lw=1.6, zorder=2, label="Pareto front")
    last = None  # label a front point only when it stands clear of the last labelled one (log distance)
    for r in front:
        here = (math.log10(r["time_s"]), math.log10(y_of(r)))
        if last is not None and abs(here[0] - last[0]) < 0.25 and abs(here[1] - last[1]) < 0.08:
            continue
        above = last is None or here[1] < last[1] - 0.08
        ax.annotate(label(r), (r["time_s"], y_of(r)), textcoords="offset points",
                    xytext=(5, 4 if above else -11), fontsize=7, color="crimson")
        last = here
for r in rows:
    if r["is_default"]:
        ax.scatter(r["time_s"], y_of(r), s=260, marker="*", c="red", edgecolors="black", zorder=5,
                   label="default (" + label(r) + ")" + (", on the front" if r["on_front"] else ", off the front"))
ax.set_xscale("log"); ax.set_yscale("log")
ax.set_xlabel("render wall time, seconds (best of repeats; accelerator build excluded)")
ax.set_ylabel("RMSE vs reference (linear RGB, all pixels and channels)")
ax.grid(True, which="both", alpha=0.25)
# PSNR (peak 1.0) on the right: the same log axis, labelled in dB.
lo, hi = ax.get_ylim()
ax2 = ax.twinx(); ax2.set_yscale("log"); ax2.set_ylim(lo, hi)
span_db = 20 * math.log10(hi / lo)
step = 10 if span_db >= 30 else (5 if span_db >= 12 else (2 if span_db >= 5 else 1))
ticks = [(p, 10 ** (-p / 20.0)) for p in range(0, 201, step) if lo <= 10 ** (-p / 20.0) <= hi]
ax2.set_yticks([t for _, t in ticks]); ax2.set_yticklabels([str(p) for p, _ in ticks]); ax2.minorticks_off()
ax2.set_ylabel("PSNR, dB (peak 1.0)")
if any(r["rmse"] == 0 for r in rows):
    subtitle += "\n(triangles: RMSE 0, drawn at {:.2g})".format(floor)
ax.set_title(title + "\n" + subtitle, fontsize=9)
ax.legend(fontsize=7, loc="best")
fig.tight_layout()
fig.savefig(png_path, dpi=120)
)PY";
  return kScript;
}

}  // namespace raynode::apps
