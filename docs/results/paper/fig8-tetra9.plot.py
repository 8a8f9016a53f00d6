#!/usr/bin/env python3
"""Plots a `raynode sweep` CSV (written by raynode; see `raynode sweep --help`).

usage: python3 PREFIX.plot.py PREFIX.csv PREFIX.png KIND [TITLE]
KIND: nodes | cache | page-size
"""
import csv
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import FuncFormatter, NullFormatter  # noqa: E402

MODE_STYLE = {
    "svm": dict(color="tab:blue", marker="o"),
    "dataflow": dict(color="tab:red", marker="s"),
    "replicated": dict(color="tab:green", marker="^"),
}


def num(row, key):
    v = row.get(key, "")
    try:
        return float(v) if v not in ("", None) else None
    except ValueError:
        return None


def plain(x, _pos=None):
    return f"{x:g}"


def series(rows, xkey, ykey, scale=1.0):
    pts = []
    for r in rows:
        x, y = num(r, xkey), num(r, ykey)
        if r.get("status") == "ok" and x is not None and y is not None:
            pts.append((x, y * scale))
    pts.sort()
    return [p[0] for p in pts], [p[1] for p in pts]


def join_notes(*notes):
    return "; ".join(n for n in notes if n)


def skipped_note(rows, label):
    bad = [label(r) for r in rows if r.get("status") != "ok"]
    return ("skipped (does not fit a node's memory): " + ", ".join(bad)) if bad else ""


def minor_log_label(ax):
    """Labels 2x and 5x minor ticks of a log axis that spans under 2 decades."""
    def label(v, _pos=None):
        lo, hi = ax.get_ylim()
        if lo <= 0 or hi / lo > 100:
            return ""
        lead = round(v / 10 ** math.floor(math.log10(v) + 1e-9))
        return plain(v) if lead in (2, 5) else ""
    return label


def log2_axis(ax, values):
    ax.set_xscale("log", base=2)
    ax.xaxis.set_major_formatter(FuncFormatter(plain))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xticks(sorted(set(values)))


def plot_nodes(rows, fig):
    ax_s, ax_e = fig.subplots(1, 2)
    modes = []
    for r in rows:
        if r["mode"] not in modes:
            modes.append(r["mode"])
    all_n = [num(r, "nodes") for r in rows if num(r, "nodes")]
    for mode in modes:
        mr = [r for r in rows if r["mode"] == mode]
        style = MODE_STYLE.get(mode, {})
        x, y = series(mr, "nodes", "speedup")
        if x:
            ax_s.plot(x, y, label=mode, **style)
        x, y = series(mr, "nodes", "efficiency", 100.0)
        if x:
            ax_e.plot(x, y, label=mode, **style)
    if all_n:
        lo, hi = min(all_n), max(all_n)
        ax_s.plot([lo, hi], [lo, hi], "k--", lw=1, label="ideal")
        for ax in (ax_s, ax_e):
            log2_axis(ax, all_n)
        ax_s.set_yscale("log", base=2)
        ax_s.yaxis.set_major_formatter(FuncFormatter(plain))
        ax_s.yaxis.set_minor_formatter(NullFormatter())
        ax_s.set_yticks(sorted(set(all_n)))
    ax_s.set_xlabel("nodes")
    ax_s.set_ylabel("speedup  T_1 / T_p")
    ax_s.set_title("Speedup")
    ax_e.set_xlabel("nodes")
    ax_e.set_ylabel("efficiency (%)")
    ax_e.set_title("Efficiency")
    ax_e.set_ylim(0, max(105, ax_e.get_ylim()[1]))
    ax_e.axhline(100, color="k", ls="--", lw=1)
    for ax in (ax_s, ax_e):
        ax.grid(True, which="major", alpha=0.3)
        ax.legend()
    return skipped_note(rows, lambda r: f"{r['mode']} {r['nodes']} nodes")


def cache_x(rows):
    xs = [num(r, "cache_percent") for r in rows if r.get("status") == "ok" and num(r, "cache_percent")]
    return xs


def set_cache_axis(ax, xs):
    if xs and min(xs) > 0 and max(xs) / min(xs) >= 20:
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(FuncFormatter(plain))
        ax.set_xlabel("cache per node (% of the database, log scale)")
    else:
        ax.set_xlabel("cache per node (% of the database)")
    ax.grid(True, which="major", alpha=0.3)


def rate_series(rows, xkey):
    """Communication rate per node: iPSC/2-equivalent MB/s under the ipsc2
    network (virtual seconds x the network's scale), else MB per virtual s."""
    ipsc = any(num(r, "ipsc2_rate_per_node_bytes_per_s") is not None for r in rows if r.get("status") == "ok")
    key = "ipsc2_rate_per_node_bytes_per_s" if ipsc else "communication_rate_per_node_bytes_per_s"
    x, y = series(rows, xkey, key, 1e-6)
    label = ("page traffic per node (MB/s, iPSC/2-equivalent)" if ipsc
             else "page traffic per node (MB per virtual s)")
    return x, y, label, ipsc


def plot_miss(ax, rows, xkey):
    x, y = series(rows, xkey, "miss_ratio", 100.0)
    if x:
        ax.plot(x, y, "o-", color="tab:purple", label="per object access")
    x, y = series(rows, xkey, "cache_miss_ratio", 100.0)
    if x:
        ax.plot(x, y, "s--", color="tab:gray", label="per non-home page lookup, full cache")
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(FuncFormatter(plain))
    ax.yaxis.set_minor_formatter(FuncFormatter(minor_log_label(ax)))
    ax.set_ylabel("miss ratio (%)")
    ax.set_title("Miss ratio")
    ax.legend(fontsize="small")


def plot_rate(ax, rows, xkey):
    """Draws the communication rate; returns a note for under the figure."""
    x, y, label, ipsc = rate_series(rows, xkey)
    if x:
        ax.plot(x, y, "o-", color="tab:orange")
    ax.set_ylabel(label)
    ax.set_title("Communication rate")
    ax.set_ylim(bottom=0)
    if ipsc:
        # The paper's reference: the iPSC/2 moves 1 KiB messages at 0.9 MB/s.
        if y and max(y) >= 0.25 * 0.9:
            ax.axhline(0.9, color="k", ls=":", lw=1)
            ax.text(0.02, 0.9, "0.9 MB/s: iPSC/2, 1 KiB messages", transform=ax.get_yaxis_transform(),
                    va="bottom", fontsize="small")
        elif y:
            return "rate per node x the ipsc2 network's scale; the iPSC/2's 0.9 MB/s for 1 KiB messages is off scale"
    return ""


def plot_efficiency(ax, rows, xkey):
    x, y = series(rows, xkey, "efficiency", 100.0)
    if x:
        ax.plot(x, y, "o-", color="tab:blue")
    ax.set_ylim(0, max(105, ax.get_ylim()[1]))
    ax.axhline(100, color="k", ls="--", lw=1)
    ax.set_ylabel("efficiency (%)")
    ax.set_title("Efficiency")


def plot_cache(rows, fig):
    axes = fig.subplots(1, 3)
    xs = cache_x(rows)
    plot_efficiency(axes[0], rows, "cache_percent")
    plot_miss(axes[1], rows, "cache_percent")
    rate_note = plot_rate(axes[2], rows, "cache_percent")
    for ax in axes:
        set_cache_axis(ax, xs)
    return join_notes(skipped_note(rows, lambda r: r.get("cache", "?")), rate_note)


def plot_page_size(rows, fig):
    axes = fig.subplots(1, 4)
    plot_efficiency(axes[0], rows, "page_size")
    plot_miss(axes[1], rows, "page_size")
    x, y = series(rows, "page_size", "pages_per_pixel")
    if x:
        axes[2].plot(x, y, "o-", color="tab:green")
    axes[2].set_ylim(bottom=0)
    axes[2].set_ylabel("distinct pages per pixel")
    axes[2].set_title("Pages per pixel")
    rate_note = plot_rate(axes[3], rows, "page_size")
    sizes = [num(r, "page_size") for r in rows if num(r, "page_size")]
    for ax in axes:
        log2_axis(ax, sizes)
        ax.set_xlabel("page size (bytes)")
        ax.grid(True, which="major", alpha=0.3)
    return join_notes(skipped_note(rows, lambda r: f"{r['page_size']} B"), rate_note)


def main(argv):
    if len(argv) < 4:
        sys.stderr.write(__doc__)
        return 2
    csv_path, png_path, kind = argv[1], argv[2], argv[3]
    title = argv[4] if len(argv) > 4 else csv_path
    with open(csv_path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get("role", "point") != "T_1"]
    width = {"nodes": 11, "cache": 15, "page-size": 19}.get(kind)
    if width is None:
        sys.stderr.write(f"unknown kind {kind!r}\n")
        return 2
    fig = plt.figure(figsize=(width, 4.6))
    if kind == "nodes":
        note = plot_nodes(rows, fig)
    elif kind == "cache":
        note = plot_cache(rows, fig)
    else:
        note = plot_page_size(rows, fig)
    fig.suptitle(title, fontsize="medium")
    if note:
        fig.text(0.01, 0.01, note, fontsize="small", color="dimgray")
    fig.tight_layout(rect=(0, 0.04 if note else 0, 1, 0.95))
    fig.savefig(png_path, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
