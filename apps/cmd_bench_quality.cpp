// `raynode bench quality SCENE`: render time against image error.
//
// Data flow: SCENE -> one Database per --tessellate level -> one accelerator
// per (level, --accel) (built once, build time reported apart) -> a reference
// image (deep, unpruned, analytic, supersampled, grid) -> for each point of
// the design: render_image, the fastest of repeats interleaved over all
// points (the timed part) -> RMSE and PSNR against the reference -> Pareto
// front (apps/pareto.h) -> table on stdout, PREFIX.csv, PREFIX.png (embedded
// matplotlib script, apps/plot.h).
//
// The error is measured on the linear float image the renderer returns
// (core::RenderResult::color), before any clamping or 8-bit quantisation.
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "apps/commands.h"
#include "apps/output_files.h"
#include "apps/pareto.h"
#include "apps/plot.h"
#include "apps/quality_plot.h"
#include "core/database.h"
#include "core/direct_view.h"
#include "core/embree_scene.h"
#include "core/embree_view.h"
#include "core/grid.h"
#include "core/render.h"
#include "core/scene_source.h"

namespace raynode::apps {

namespace {

/// PSNR peak: the linear image's nominal white (what an LDR file maps to 255).
constexpr double kPsnrPeak = 1.0;

/// Most renders timed for one point (--min-time stops sooner).
constexpr int kMaxRenders = 1000;

/// Significant digits of the RMSE that the Pareto front tells apart.
constexpr int kFrontDigits = 3;

/// `v` rounded to `digits` significant decimal digits (0, inf, NaN unchanged).
double round_significant(double v, int digits) {
  if (v == 0 || !std::isfinite(v)) return v;
  const double scale = std::pow(10.0, digits - 1 - int(std::floor(std::log10(std::fabs(v)))));
  return std::round(v * scale) / scale;
}

/// One point of the design: the render command's quality knobs.
struct Settings {
  int max_depth = 5;
  float min_weight = 0.0f;
  int tessellate = 0;
  int spp = 1;
  std::string accel = "grid";

  auto key() const { return std::tie(max_depth, min_weight, tessellate, spp, accel); }
  bool operator==(const Settings& o) const { return key() == o.key(); }
  bool operator<(const Settings& o) const { return key() < o.key(); }
};

/// The render command's defaults (apps/cmd_render.cpp, core::RenderParams):
/// always a point of the sweep, and the centre of the star and pairs designs.
const Settings kDefaults{};

struct QualityOptions {
  std::string scene;
  core::ViewOverride view;  ///< --eye, --at, --up, --fov
  std::string max_depths = "1,2,3,5,8";
  std::string min_weights = "0,0.001,0.01,0.1";
  std::string tessellations = "0,1,2,4";
  std::string spps = "1,2,3";
  std::string accels = "grid,embree";
  GridChoice grid;  ///< --grid for the grid accelerator (default adaptive)
  std::string design = "pairs";
  int max_points = 200;
  int width = 128, height = 128;
  bool full = false;
  int repeat = 3;
  double min_time_s = 0.2;  ///< keep repeating a point until this much render time is spent on it
  std::string mode = "sequential";
  int reference_spp = 4;
  int reference_depth = 16;
  int check_depth = 0;  ///< 0 = reference_depth + 8
  int check_spp = 1;    ///< samples per pixel (N x N) of the stability check
  std::string output;   ///< PREFIX; "" = quality-<scene>
  bool no_plot = false;
  bool quiet = false;
};

/// The knob lists after parsing, each non-empty, in the order given, without repeats.
struct Knobs {
  std::vector<int> max_depth;
  std::vector<float> min_weight;
  std::vector<int> tessellate;
  std::vector<int> spp;
  std::vector<std::string> accel;
};

std::vector<std::string> split_list(const std::string& option, const std::string& text) {
  std::vector<std::string> items;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (item.empty())
      throw UsageError(fmt::format("{}: empty entry in the list '{}' (give comma-separated values, e.g. 1,2,3)",
                                   option, text));
    items.push_back(item);
  }
  if (items.empty()) throw UsageError(fmt::format("{}: the list is empty; give at least one value", option));
  return items;
}

template <class T>
void push_unique(std::vector<T>& v, const T& x) {
  if (std::find(v.begin(), v.end(), x) == v.end()) v.push_back(x);
}

/// Comma-separated integers in [lo, hi]; throws UsageError naming the option.
std::vector<int> parse_int_list(const std::string& option, const std::string& text, int lo, int hi,
                                const char* what) {
  std::vector<int> out;
  for (const std::string& s : split_list(option, text)) {
    char* end = nullptr;
    const long v = std::strtol(s.c_str(), &end, 10);
    if (end == s.c_str() || *end != '\0')
      throw UsageError(fmt::format("{}: '{}' is not a whole number", option, s));
    if (v < lo || v > hi) throw UsageError(fmt::format("{}: {} must be in [{}, {}], got {}", option, what, lo, hi, v));
    push_unique(out, int(v));
  }
  return out;
}

Knobs parse_knobs(const QualityOptions& o) {
  Knobs k;
  k.max_depth = parse_int_list("--max-depth", o.max_depths, 1, 64, "a depth (ray levels, eye ray = 1)");
  for (const std::string& s : split_list("--min-weight", o.min_weights)) {
    char* end = nullptr;
    const float v = std::strtof(s.c_str(), &end);
    if (end == s.c_str() || *end != '\0') throw UsageError(fmt::format("--min-weight: '{}' is not a number", s));
    if (!(v >= 0.0f && v <= 1.0f)) throw UsageError(fmt::format("--min-weight: a weight must be in [0, 1], got {}", s));
    push_unique(k.min_weight, v);
  }
  k.tessellate = parse_int_list("--tessellate", o.tessellations, 0, 1000, "a tessellation level R (0 = curved)");
  k.spp = parse_int_list("--spp", o.spps, 1, 64, "N (N x N samples per pixel)");
  for (const std::string& s : split_list("--accel", o.accels)) {
    if (s != "grid" && s != "embree")
      throw UsageError(fmt::format("--accel: unknown accelerator '{}' (grid or embree)", s));
    push_unique(k.accel, s);
  }
  return k;
}

/// Knob names as the render command spells its options.
constexpr const char* kKnobNames[5] = {"max-depth", "min-weight", "tessellate", "spp", "accel"};

/// "default", or the knobs in which `s` differs from the defaults, joined by '+'.
std::string varied_knobs(const Settings& s) {
  std::string v;
  const bool differs[5] = {s.max_depth != kDefaults.max_depth, s.min_weight != kDefaults.min_weight,
                           s.tessellate != kDefaults.tessellate, s.spp != kDefaults.spp, s.accel != kDefaults.accel};
  for (int i = 0; i < 5; ++i)
    if (differs[i]) v += (v.empty() ? "" : "+") + std::string(kKnobNames[i]);
  return v.empty() ? "default" : v;
}

/// Copies of `base` with knob `knob` (0..4) set to each value of its list.
std::vector<Settings> vary(const Settings& base, int knob, const Knobs& k) {
  std::vector<Settings> out;
  auto add = [&](auto set) {
    Settings s = base;
    set(s);
    out.push_back(s);
  };
  switch (knob) {
    case 0: for (int v : k.max_depth) add([v](Settings& s) { s.max_depth = v; }); break;
    case 1: for (float v : k.min_weight) add([v](Settings& s) { s.min_weight = v; }); break;
    case 2: for (int v : k.tessellate) add([v](Settings& s) { s.tessellate = v; }); break;
    case 3: for (int v : k.spp) add([v](Settings& s) { s.spp = v; }); break;
    default: for (const std::string& v : k.accel) add([&v](Settings& s) { s.accel = v; }); break;
  }
  return out;
}

/// The points to measure, the default first, no repeats. star: the default
/// and each knob's list with the other knobs at their defaults; pairs: star
/// plus, for every two knobs, their lists crossed with the rest at the
/// defaults; full: the cross-product of all lists (plus the default).
/// Throws UsageError for an unknown design or more than max_points points.
std::vector<Settings> make_design(const std::string& design, const Knobs& k, int max_points) {
  std::vector<Settings> points{kDefaults};
  std::set<Settings> seen{kDefaults};
  auto add = [&](const Settings& s) {
    if (seen.insert(s).second) points.push_back(s);
  };
  if (design == "star" || design == "pairs") {
    for (int a = 0; a < 5; ++a)
      for (const Settings& s : vary(kDefaults, a, k)) add(s);
    if (design == "pairs")
      for (int a = 0; a < 5; ++a)
        for (int b = a + 1; b < 5; ++b)
          for (const Settings& s : vary(kDefaults, a, k))
            for (const Settings& t : vary(s, b, k)) add(t);
  } else if (design == "full") {
    const std::size_t n = k.max_depth.size() * k.min_weight.size() * k.tessellate.size() * k.spp.size() *
                          k.accel.size();
    if (n > std::size_t(max_points))  // checked before building: the product can be huge
      throw UsageError(fmt::format("--design full gives {} points, more than --max-points {}; shorten the lists, "
                                   "choose a smaller design or raise --max-points",
                                   n, max_points));
    std::vector<Settings> level{kDefaults};
    for (int a = 0; a < 5; ++a) {
      std::vector<Settings> next;
      for (const Settings& s : level)
        for (const Settings& t : vary(s, a, k)) next.push_back(t);
      level = std::move(next);
    }
    for (const Settings& s : level) add(s);
  } else {
    throw UsageError("--design must be star, pairs or full, got '" + design + "'");
  }
  if (points.size() > std::size_t(max_points))
    throw UsageError(fmt::format("--design {} gives {} points, more than --max-points {}; shorten the lists, choose "
                                 "a smaller design or raise --max-points",
                                 design, points.size(), max_points));
  return points;
}

/// A database at one tessellation level with the accelerators built for it so far.
struct Prepared {
  std::unique_ptr<core::Database> db;  // heap: the views keep pointers to it
  std::optional<core::Grid> grid;
  double grid_build_s = 0;
  std::unique_ptr<core::EmbreeScene> embree;
  double embree_build_s = 0;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// The database for `tessellate` with the accelerator `accel` built (cached).
Prepared& prepare(std::map<int, Prepared>& cache, const std::string& scene, const core::ViewOverride& view,
                  int tessellate, const std::string& accel, core::GridKind grid_kind) {
  Prepared& p = cache[tessellate];
  if (!p.db) {
    core::SceneSource source = tracing_source(scene, tessellate);
    source.view = view;
    p.db = std::make_unique<core::Database>(core::make_database(core::load_scene(source)));
  }
  const auto t0 = std::chrono::steady_clock::now();
  if (accel == "embree" && !p.embree) {
    p.embree = std::make_unique<core::EmbreeScene>(*p.db);
    p.embree_build_s = seconds_since(t0);
  } else if (accel == "grid" && !p.grid) {
    core::GridParams gp;
    gp.kind = grid_kind;
    p.grid = core::build_grid(*p.db, gp);
    p.grid_build_s = seconds_since(t0);
  }
  return p;
}

/// One render of `p` through `accel`; returns the result, and its wall seconds in `seconds`.
core::RenderResult render_timed(const Prepared& p, const std::string& accel, const core::RenderParams& params,
                                double& seconds) {
  const auto t0 = std::chrono::steady_clock::now();
  core::RenderResult r = accel == "embree" ? core::render_image(core::EmbreeView(*p.db, *p.embree), *p.db, params)
                                           : core::render_image(core::DirectView(*p.db, *p.grid), *p.db, params);
  seconds = seconds_since(t0);
  return r;
}

/// Root mean square difference over all pixels and channels of two images
/// of the same shape (throws std::logic_error otherwise).
double rmse(const core::Image& a, const core::Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels || a.pixels.size() != b.pixels.size())
    throw std::logic_error(fmt::format("rmse: image shapes differ: {}x{}x{} vs {}x{}x{}", a.width, a.height,
                                       a.channels, b.width, b.height, b.channels));
  double sum = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    const double d = double(a.pixels[i]) - double(b.pixels[i]);
    sum += d * d;
  }
  return a.pixels.empty() ? 0.0 : std::sqrt(sum / double(a.pixels.size()));
}

/// PSNR in dB for peak kPsnrPeak; +inf for a zero error.
double psnr(double rmse_value) {
  return rmse_value > 0 ? 20.0 * std::log10(kPsnrPeak / rmse_value) : INFINITY;
}

std::string fmt_psnr(double p) { return std::isinf(p) ? "inf" : fmt::format("{:.2f}", p); }

std::string fmt_duration(double s) {
  if (s < 60) return fmt::format("{:.0f} s", s);
  return fmt::format("{}m{:02d}s", int(s) / 60, int(s) % 60);
}

std::string describe(const Settings& s) {
  return fmt::format("max-depth {} min-weight {:g} tessellate {} spp {} accel {}", s.max_depth, s.min_weight,
                     s.tessellate, s.spp, s.accel);
}

/// A measured point.
struct Measured {
  Settings s;
  std::string varied;
  std::size_t primitives = 0;
  double build_s = 0;  ///< accelerator build for (tessellate, accel), wall seconds, once
  double time_s = 0;   ///< best render wall seconds of `renders`
  int renders = 0;     ///< renders timed: at least --repeat, more until --min-time is spent
  double first_s = 0;  ///< wall seconds of the first render (plans the repeats)
  std::uint64_t rays = 0;
  double rmse = 0;
  double psnr = 0;
  bool on_front = false;
  bool is_default = false;
};

/// "teapot:8" -> "quality-teapot-8"; a file path -> "quality-<stem>".
std::string default_prefix(const std::string& scene) {
  std::string base = core::is_scene_file(scene) ? std::filesystem::path(scene).filename().string() : scene;
  for (const char* ext : {".gz", ".nff"})
    if (base.size() > std::string(ext).size() && base.ends_with(ext)) base.resize(base.size() - std::string(ext).size());
  for (char& c : base)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '-';
  return "quality-" + base;
}

/// The CSV of the points measured so far (renders > 0), the front among them.
std::string csv_text(const QualityOptions& o, int w, int h, const std::vector<Measured>& points) {
  std::vector<std::size_t> measured;
  std::vector<CostPoint> costs;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (points[i].renders > 0) {
      measured.push_back(i);
      costs.push_back({points[i].time_s, round_significant(points[i].rmse, kFrontDigits)});
    }
  std::vector<bool> on_front(points.size(), false);
  for (std::size_t k : pareto_front(costs)) on_front[measured[k]] = true;
  const double default_time = points.empty() ? 0.0 : points.front().time_s;  // make_design puts it first
  std::string out =
      "index,scene,width,height,max_depth,min_weight,tessellate,spp,accel,mode,varied,primitives,build_s,time_s,"
      "renders,time_over_default,rays,rmse,psnr_db,on_front,is_default\n";
  for (std::size_t i : measured) {
    const Measured& m = points[i];
    out += fmt::format("{},\"{}\",{},{},{},{:g},{},{},{},{},{},{},{:.6g},{:.6g},{},{:.4g},{},{:.6g},{},{},{}\n", i,
                       o.scene, w, h, m.s.max_depth, m.s.min_weight, m.s.tessellate, m.s.spp, m.s.accel, o.mode,
                       m.varied, m.primitives, m.build_s, m.time_s, m.renders, m.time_s / default_time, m.rays,
                       m.rmse, fmt_psnr(m.psnr), int(on_front[i]), int(m.is_default));
  }
  return out;
}

/// The sweep's reference image and how far its own depth limit could move
/// a measured error.
struct Reference {
  core::Image image;
  double seconds = 0;    ///< the reference render's wall seconds
  double stability = 0;  ///< RMSE between renders at --reference-depth and --check-depth (at --check-spp)
  double check_s = 0;    ///< the stability check's wall seconds
};

/// The reference: deep, unpruned, analytic, supersampled, grid. Rendered in
/// shared mode (all cores) to save time: its image is bit-identical to
/// sequential mode's (core/render.h); its time is not part of the sweep.
/// Stability: the reference's depth against a deeper one, at --check-spp.
/// At 1 sample per pixel the check compares single samples, whose
/// differences averaging over N x N samples can only shrink (in
/// expectation): a conservative check, N^2 times cheaper than at the
/// reference's spp, which matters where glass makes the ray tree grow
/// (mount:6 at max-depth 24 costs 27 times as much as at 16).
Reference render_reference(const QualityOptions& o, Prepared& analytic, const core::RenderParams& base, bool show) {
  Reference r;
  core::RenderParams ref_params = base;
  ref_params.spp = o.reference_spp;
  ref_params.max_depth = o.reference_depth;
  ref_params.min_weight = 0.0f;
  ref_params.mode = core::RenderMode::kShared;
  if (show)
    fmt::print(stderr, "bench quality: reference {}x{}, spp {}x{}, max-depth {}, min-weight 0, analytic, grid...\n",
               o.width, o.height, o.reference_spp, o.reference_spp, o.reference_depth);
  r.image = render_timed(analytic, "grid", ref_params, r.seconds).color;
  core::RenderParams shallow_params = ref_params;
  shallow_params.spp = o.check_spp;
  core::RenderParams deep_params = shallow_params;
  deep_params.max_depth = o.check_depth;
  double shallow_s = 0;
  core::Image shallow_image;
  if (o.check_spp != o.reference_spp) shallow_image = render_timed(analytic, "grid", shallow_params, shallow_s).color;
  const core::Image& shallow = o.check_spp == o.reference_spp ? r.image : shallow_image;
  r.stability = rmse(render_timed(analytic, "grid", deep_params, r.check_s).color, shallow);
  r.check_s += shallow_s;
  if (show)
    fmt::print(stderr,
               "bench quality: reference {:.2f} s, stability check (max-depth {} vs {}, spp {}) {:.2f} s: RMSE {:.3g}\n",
               r.seconds, o.reference_depth, o.check_depth, o.check_spp, r.check_s, r.stability);
  return r;
}

/// Measures every point of `design` against `reference`, in rounds: round 1
/// renders every point once (its image gives the error and the ray count,
/// its time plans the repeats); each later round renders again every point
/// that still needs renders (at least --repeat in all, more until
/// --min-time is spent), keeping the fastest. Interleaving the repeats
/// spreads a burst of load from other processes over many points instead
/// of spoiling every render of one; the minimum filters it out (noise only
/// ever adds time). The CSV is replaced after every point and round.
std::vector<Measured> measure_points(const QualityOptions& o, const std::vector<Settings>& design,
                                     std::map<int, Prepared>& cache, const core::RenderParams& base,
                                     const core::Image& reference, OutputFiles& files, std::size_t csv_out, bool show) {
  std::vector<Measured> points(design.size());
  std::vector<Prepared*> prepared(design.size());
  std::vector<core::RenderParams> params(design.size(), base);
  std::vector<int> planned(design.size(), 0);
  const core::RenderMode mode = core::parse_render_mode(o.mode);
  for (std::size_t i = 0; i < design.size(); ++i) {
    const Settings& s = design[i];
    Measured& m = points[i];
    m.s = s;
    m.varied = varied_knobs(s);
    m.is_default = s == kDefaults;
    m.time_s = INFINITY;
    params[i].spp = s.spp;
    params[i].max_depth = s.max_depth;
    params[i].min_weight = s.min_weight;
    params[i].mode = mode;
  }
  // ETA: a point's expected render time is max(repeat x t, min-time), t its
  // first render, or (not rendered yet) the seconds per sample so far x spp^2.
  double first_s = 0, first_samples = 0, spent = 0;
  auto expected = [&](std::size_t i) {
    const double t = points[i].renders > 0 ? points[i].first_s
                                           : (first_samples > 0 ? first_s / first_samples : 0.0) *
                                                 double(design[i].spp * design[i].spp);
    return std::max(double(o.repeat) * t, std::min(o.min_time_s, kMaxRenders * t));
  };
  auto eta = [&] {
    double total = 0;
    for (std::size_t i = 0; i < design.size(); ++i) total += expected(i);
    return fmt_duration(std::max(0.0, total - spent));
  };
  auto render_point = [&](std::size_t i) {
    Measured& m = points[i];
    double t = 0;
    core::RenderResult result = render_timed(*prepared[i], design[i].accel, params[i], t);
    if (m.renders == 0) {  // every render of a point gives the same image and counts
      m.rmse = rmse(result.color, reference);
      m.psnr = psnr(m.rmse);
      m.rays = result.stats.rays.total();
      m.first_s = t;
    }
    m.time_s = std::min(m.time_s, t);
    ++m.renders;
    spent += t;
  };
  for (std::size_t i = 0; i < design.size(); ++i) {
    const Settings& s = design[i];
    prepared[i] = &prepare(cache, o.scene, o.view, s.tessellate, s.accel, grid_kind_for(o.grid));
    Measured& m = points[i];
    m.primitives = prepared[i]->db->primitives.size();
    m.build_s = s.accel == "embree" ? prepared[i]->embree_build_s : prepared[i]->grid_build_s;
    render_point(i);
    first_s += m.first_s;
    first_samples += double(s.spp * s.spp);
    const double wanted = m.first_s > 0 ? std::ceil(o.min_time_s / m.first_s) : double(kMaxRenders);
    planned[i] = int(std::clamp(wanted, double(o.repeat), double(kMaxRenders)));
    if (show)
      fmt::print(stderr, "bench quality: point {}/{} ({}): {:.4f} s, RMSE {:.3g}; {} renders planned; ETA {}\n",
                 i + 1, design.size(), describe(s), m.first_s, m.rmse, planned[i], eta());
    files.update(csv_out, csv_text(o, o.width, o.height, points));
  }
  const int rounds = *std::max_element(planned.begin(), planned.end());
  for (int round = 2; round <= rounds; ++round) {
    std::size_t count = 0;
    for (std::size_t i = 0; i < design.size(); ++i)
      if (planned[i] >= round) {
        render_point(i);
        ++count;
      }
    if (show && (round <= 3 || round % 10 == 0 || round == rounds))
      fmt::print(stderr, "bench quality: repeat round {}/{} ({} points); ETA {}\n", round, rounds, count, eta());
    files.update(csv_out, csv_text(o, o.width, o.height, points));
  }

  return points;
}

/// Prints the table of `points`, the Pareto front (whose members it marks
/// in `points`) and what it says of the default; returns the smallest
/// non-zero error measured.
double print_table(const QualityOptions& o, std::vector<Measured>& points) {
  // The front compares errors to kFrontDigits significant digits (as the
  // table prints them): two renders whose errors differ in the fourth digit
  // (e.g. grid vs Embree picking another primitive at a few grazing pixels)
  // are equally good, and the faster one wins.
  std::vector<CostPoint> costs;
  for (const Measured& m : points) costs.push_back({m.time_s, round_significant(m.rmse, kFrontDigits)});
  for (std::size_t i : pareto_front(costs)) points[i].on_front = true;
  double smallest = INFINITY;
  for (const Measured& m : points)
    if (m.rmse > 0) smallest = std::min(smallest, m.rmse);

  const Measured& def = points.front();  // make_design puts the default first
  // The table.
  fmt::print("bench quality {}: {}x{}, mode {} ({}); time = best render wall time of at least {} renders and "
             "at least {:g} s per point (n = renders timed); accelerator build excluded (build s: once per "
             "tessellation and accelerator)\n",
             o.scene, o.width, o.height, o.mode,
             o.mode == "sequential" ? "one thread" : "TBB threads on all cores", o.repeat, o.min_time_s);
  fmt::print("{:>3} {:>5} {:>6} {:>4} {:>3} {:>6} {:>7} {:>7} {:>9} {:>4} {:>6} {:>9} {:>9} {:>7}  {}\n", "#",
             "depth", "weight", "tess", "spp", "accel", "prims", "build s", "time s", "n", "x def", "rays", "RMSE",
             "PSNR dB", "mark");
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Measured& m = points[i];
    std::string mark = m.on_front ? "front" : "";
    if (m.is_default) mark += mark.empty() ? "default" : " default";
    fmt::print("{:>3} {:>5} {:>6g} {:>4} {:>3} {:>6} {:>7} {:>7.3f} {:>9.4f} {:>4} {:>6.2f} {:>9} {:>9.3g} {:>7}  {}\n",
               i, m.s.max_depth, m.s.min_weight, m.s.tessellate, m.s.spp, m.s.accel, m.primitives, m.build_s,
               m.time_s, m.renders, m.time_s / def.time_s, m.rays, m.rmse, fmt_psnr(m.psnr), mark);
  }
  fmt::print("Pareto front (no other point is both faster and closer to the reference, RMSE compared to {} "
             "significant digits), fastest first:\n",
             kFrontDigits);
  std::vector<std::size_t> front = pareto_front(costs);
  for (std::size_t i : front)
    fmt::print("  #{:<3} {:.4f} s  RMSE {:.3g}  PSNR {} dB  {}{}\n", i, points[i].time_s, points[i].rmse,
               fmt_psnr(points[i].psnr), describe(points[i].s), points[i].is_default ? "  (default)" : "");
  if (def.on_front) {
    fmt::print("The default ({}) is on the front.\n", describe(def.s));
  } else {
    // The front point that beats the default by the most time at no more error.
    std::size_t best = front.front();
    for (std::size_t i : front)
      if (costs[i].x <= costs[0].x && costs[i].y <= costs[0].y) {
        best = i;
        break;
      }
    fmt::print("The default ({}) is off the front: #{} ({}) takes {:.4f} s (x{:.2f}) for RMSE {:.3g} (default: {:.4f} "
               "s, RMSE {:.3g}).\n",
               describe(def.s), best, describe(points[best].s), points[best].time_s,
               points[best].time_s / def.time_s, points[best].rmse, def.time_s, def.rmse);
  }
  fmt::print("Error: RMSE over all pixels and RGB channels of the linear float image (before clamping or 8-bit "
             "quantisation); PSNR = 20 log10({:.1f} / RMSE) dB.\n",
             kPsnrPeak);
  return smallest;
}

/// Prints the reference's description and how stable it is against a
/// deeper one, relative to the smallest error measured.
void print_reference(const QualityOptions& o, const Reference& ref, double smallest) {
  fmt::print("Reference: {}x{}, spp {}x{} = {} samples, max-depth {}, min-weight 0, analytic (tessellate 0), grid; "
             "{:.2f} s (shared mode, same image as sequential).\n",
             o.width, o.height, o.reference_spp, o.reference_spp, o.reference_spp * o.reference_spp,
             o.reference_depth, ref.seconds);
  const double stability = ref.stability;
  // RMSE is a norm, so (triangle inequality) a point's RMSE against the
  // reference and against a deeper reference differ by at most their
  // distance: `stability` bounds how far the reference's own depth limit can
  // move any measured error; relative to the smallest error it is the worst
  // case relative change.
  const double relative = stability == 0 ? 0.0 : stability / smallest;
  const std::string stability_text =
      fmt::format("max-depth {} vs {} (spp {}x{}): RMSE {:.3g} (PSNR {} dB) = {:.3g}x the smallest sweep error {:.3g}",
                  o.reference_depth, o.check_depth, o.check_spp, o.check_spp, stability, fmt_psnr(psnr(stability)),
                  relative, smallest);
  std::string verdict;
  if (relative <= 0.1)
    verdict = fmt::format("stable: the reference's depth limit moves no measured RMSE by more than {:.2g}%",
                          100 * relative);
  else if (relative <= 0.5)
    verdict = fmt::format("marginal: the smallest measured errors may be off by up to {:.0f}%; raise "
                          "--reference-depth, or check at the reference's spp (--check-spp {})",
                          100 * relative, o.reference_spp);
  else
    verdict = "NOT stable: the reference is not converged in depth; raise --reference-depth";
  fmt::print("Reference stability: {} -> {}.\n", stability_text, verdict);
}

/// Writes the CSV and draws the plot (or, with --no-plot, leaves its script).
void write_outputs(const QualityOptions& o, const std::string& prefix, const std::vector<Measured>& points,
                   double stability, OutputFiles& files, std::size_t csv_out) {
  const std::string csv_path = prefix + ".csv", png_path = prefix + ".png";
  files.text(csv_out, csv_text(o, o.width, o.height, points));
  files.commit();
  fmt::print("CSV: {}\n", csv_path);
  const std::string title =
      fmt::format("raynode bench quality {}: {}x{}, {} ({}), best of >= {} renders and >= {:g} s per point", o.scene,
                  o.width, o.height, o.mode, o.mode == "sequential" ? "one thread" : "all cores", o.repeat,
                  o.min_time_s);
  const std::string subtitle = fmt::format(
      "reference: spp {}x{}, max-depth {}, min-weight 0, analytic, grid; stability: depth {} vs {} RMSE {:.2g}",
      o.reference_spp, o.reference_spp, o.reference_depth, o.reference_depth, o.check_depth, stability);
  const std::vector<std::string> args{csv_path, png_path, title, subtitle};
  const std::string script_path = prefix + ".plot.py";
  if (o.no_plot) {
    std::ofstream f(script_path);
    f << quality_plot_script();
    if (!f) throw std::runtime_error("cannot write the plot script " + script_path);
    fmt::print("Plot script (not run, --no-plot): python3 {} '{}' '{}' '{}' '{}'\n", script_path, csv_path, png_path,
               title, subtitle);
  } else {
    const PlotOutcome plot = run_plot_script(quality_plot_script(), script_path, args);
    if (plot.ran) fmt::print("Plot: {}\n", png_path);
    else fmt::print("Plot not made ({}); the CSV stands. To plot later: {}\n", plot.message, plot.command);
  }
}

void run_quality(QualityOptions o) {
  // Everything the user typed is checked before the first render.
  const Knobs knobs = parse_knobs(o);
  const std::vector<Settings> design = make_design(o.design, knobs, o.max_points);
  if (o.full) o.width = o.height = 512;
  if (o.check_depth == 0) o.check_depth = std::min(64, o.reference_depth + 8);
  if (o.check_depth == o.reference_depth)
    throw UsageError(fmt::format("--check-depth must differ from --reference-depth ({})", o.reference_depth));
  const std::string prefix = o.output.empty() ? default_prefix(o.scene) : o.output;
  // The outputs are checked before the first render; the CSV then holds
  // every point measured so far, so an interrupted run keeps them.
  OutputFiles files(core::is_scene_file(o.scene) ? std::vector<std::string>{o.scene} : std::vector<std::string>{});
  const std::size_t csv_out = files.add(prefix + ".csv", "CSV", true);
  files.add(prefix + ".png", "plot", false);  // drawn by the plot script; checked here
  const bool show = !o.quiet;
  const int max_spp = *std::max_element(knobs.spp.begin(), knobs.spp.end());
  const int max_depth = *std::max_element(knobs.max_depth.begin(), knobs.max_depth.end());
  if (max_spp >= o.reference_spp)
    fmt::print(stderr,
               "raynode: warning: --spp {} is not below --reference-spp {}: the reference no longer resolves that "
               "point's aliasing\n",
               max_spp, o.reference_spp);
  if (max_depth >= o.reference_depth)
    fmt::print(stderr, "raynode: warning: --max-depth {} is not below --reference-depth {}\n", max_depth,
               o.reference_depth);

  std::map<int, Prepared> cache;
  core::RenderParams base;
  base.width = o.width;
  base.height = o.height;

  const auto t_all = std::chrono::steady_clock::now();
  Prepared& analytic = prepare(cache, o.scene, o.view, 0, "grid", grid_kind_for(o.grid));
  const Reference ref = render_reference(o, analytic, base, show);
  std::vector<Measured> points = measure_points(o, design, cache, base, ref.image, files, csv_out, show);
  const double smallest = print_table(o, points);
  print_reference(o, ref, smallest);
  write_outputs(o, prefix, points, ref.stability, files, csv_out);
  if (show) fmt::print(stderr, "bench quality: {} points in {}\n", points.size(), fmt_duration(seconds_since(t_all)));
}

}  // namespace

void register_bench_quality_command(CLI::App& app) {
  CLI::App* bench = app.get_subcommand("bench");
  auto o = std::make_shared<QualityOptions>();
  CLI::App* c = bench->add_subcommand(
      "quality", "Render time against image error (RMSE, PSNR) over the quality knobs, with the Pareto front");
  c->footer(
      "Each point renders SCENE with one setting of the knobs (--max-depth, --min-weight, --tessellate, --spp,\n"
      "--accel: comma-separated lists) and measures its error against a reference render of the same scene and\n"
      "size: --reference-depth (16) levels, min-weight 0, analytic primitives (tessellate 0), --reference-spp\n"
      "(4) squared samples, grid.\n"
      "Reference stability: the reference is rendered again at --check-depth (reference depth + 8) and the\n"
      "difference printed. RMSE is a norm, so this difference bounds how far the reference's own depth limit\n"
      "moves any measured RMSE (verdict: stable under a tenth of the smallest measured error, marginal up to\n"
      "half). The check runs at --check-spp 1 sample per pixel by default: single-sample differences, which\n"
      "averaging over the reference's samples can only shrink (in expectation), so the check is conservative\n"
      "and 16 times cheaper; the deeper render can cost many times the reference where glass makes the ray tree\n"
      "grow (mount:6: 27x). --check-spp 4 makes it exact for the default reference.\n"
      "Design (--design):\n"
      "  star   the default point and each knob's list with every other knob at its default (one at a time)\n"
      "  pairs  star, plus every two knobs' lists crossed with the rest at the defaults (the default design;\n"
      "         79 points with the default lists)\n"
      "  full   the cross-product of all five lists (480 points with the default lists: raise --max-points)\n"
      "The render command's defaults (max-depth 5, min-weight 0, tessellate 0, spp 1, accel grid) are always a\n"
      "point, even when a list leaves a default value out; they are marked 'default' in the table and CSV and\n"
      "drawn as a star in the plot. More than --max-points points is an error (exit 2).\n"
      "Pareto front: the points that no other point beats in both time and RMSE, the RMSE compared to 3\n"
      "significant digits (as printed), so that a slower render with an error smaller only in the fourth digit\n"
      "does not make the front.\n"
      "Time: wall seconds of render_image only, the fastest of at least --repeat renders and of as many more as\n"
      "fit in --min-time (short renders are noisy; noise only adds time), one thread (--mode sequential) unless\n"
      "--mode shared. The repeats run in rounds over all points, so that a burst of load from another process\n"
      "spoils one render of many points, not every render of one. Loading, tessellation and the accelerator\n"
      "build are excluded (the build is reported once per tessellation level and accelerator in the 'build s'\n"
      "column).\n"
      "Error: RMSE over all pixels and RGB channels of the linear float image before any quantisation; PSNR =\n"
      "20 log10(1.0 / RMSE) dB (peak 1.0, the image's nominal white).\n"
      "Output: a table on stdout (front and default marked), PREFIX.csv, PREFIX.plot.py and PREFIX.png (log-log\n"
      "time vs RMSE, PSNR on the right axis, the Pareto front as a step line); without a python3 that has\n"
      "matplotlib the CSV stays and the command to plot later is printed. Progress (point i of n, ETA) on\n"
      "stderr unless --quiet.\n"
      "Size: 128x128 by default (teapot:8: 20-35 s on 2 cores, rings:4 and mount:6 about a minute); --full\n"
      "renders 512x512.\n"
      "Exit status: 0 ok; 1 unreadable scene or write error; 2 bad option or value (empty list, negative depth,\n"
      "spp 0, unknown accelerator, too many points).\n"
      "Example: raynode bench quality rings:4 --max-depth 1,2,3,5,8 --spp 1,2 --design star -o rings-quality");
  c->add_option("scene", o->scene,
                "NFF file (.nff, .nff.gz), mesh file (docs/meshes.md) or built-in SPD scene name[:size]: teapot, "
                "mount, rings, tetra, balls, gears, tree, lattice, shells, jacks, sombrero")
      ->required();
  add_camera_options(*c, o->view);
  c->add_option("--max-depth", o->max_depths, "Ray levels to try (eye ray = 1), comma-separated, each in [1, 64]")
      ->capture_default_str();
  c->add_option("--min-weight", o->min_weights, "Pruning thresholds to try (0 = off), comma-separated, in [0, 1]")
      ->capture_default_str();
  c->add_option("--tessellate,-t", o->tessellations,
                "Tessellation levels R to try (0 = analytic spheres and cones; R: 12R^2 triangles per sphere, 8R per "
                "cone), comma-separated")
      ->capture_default_str();
  c->add_option("--spp", o->spps, "N to try (N x N stratified samples per pixel), comma-separated, in [1, 64]")
      ->capture_default_str();
  c->add_option("--accel", o->accels, "Accelerators to try: grid, embree (comma-separated)")->capture_default_str();
  add_grid_option(*c, o->grid);
  c->add_option("--design", o->design, "Which points: star, pairs or full (see below)")
      ->check(CLI::IsMember({"star", "pairs", "full"}))
      ->capture_default_str();
  c->add_option("--max-points", o->max_points, "Refuse designs with more points than this")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  CLI::Option* w = c->add_option("--width", o->width, "Image width in pixels")->check(CLI::Range(1, 16384));
  CLI::Option* h = c->add_option("--height", o->height, "Image height in pixels")->check(CLI::Range(1, 16384));
  w->capture_default_str();
  h->capture_default_str();
  c->add_flag("--full", o->full, "Render 512x512 (the SPD size) instead of the default 128x128")->excludes(w)->excludes(h);
  c->add_option("--repeat", o->repeat, "Renders per point at least; the fastest is kept")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  c->add_option("--min-time", o->min_time_s,
                "Seconds of rendering per point: short renders are repeated beyond --repeat until this much is spent "
                "(at most 1000 renders); the fastest is kept")
      ->check(finite_range(0, 3600))
      ->capture_default_str();
  c->add_option("--mode", o->mode, "sequential (one thread, the default) or shared (TBB threads on all cores)")
      ->check(CLI::IsMember({"sequential", "shared"}))
      ->capture_default_str();
  c->add_option("--reference-spp", o->reference_spp, "Reference: N x N samples per pixel")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  c->add_option("--reference-depth", o->reference_depth, "Reference: ray levels")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  c->add_option("--check-depth", o->check_depth,
                "Reference stability check: the reference rendered again at this depth (default: reference depth + 8, "
                "at most 64)")
      ->check(CLI::Range(1, 64));
  c->add_option("--check-spp", o->check_spp,
                "Reference stability check at N x N samples (1: conservative and cheap, see below; the reference's "
                "spp: exact)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  c->add_option("-o,--output", o->output, "PREFIX of PREFIX.csv, PREFIX.plot.py, PREFIX.png (default: quality-SCENE)");
  c->add_flag("--no-plot", o->no_plot, "Write the CSV and the plot script but do not run it");
  c->add_flag("--quiet,-q", o->quiet, "No progress lines on stderr");
  c->callback([o] { run_quality(*o); });
}

}  // namespace raynode::apps
