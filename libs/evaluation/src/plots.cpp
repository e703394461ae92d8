#include "uwbloc/evaluation/plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>
#include <tuple>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace fs = std::filesystem;

namespace uwbloc::eval {

namespace {

// Okabe and Ito's palette (BGR), distinguishable with every common colour-vision deficiency.
// The reference is black; methods cycle through the rest, then change the dash pattern.
const cv::Scalar kBlack(0, 0, 0), kOrange(0, 159, 230), kSkyBlue(233, 180, 86), kGreen(115, 158, 0),
    kYellow(66, 228, 240), kBlue(178, 114, 0), kVermillion(0, 94, 213), kPurple(167, 121, 204),
    kGrey(150, 150, 150);
const std::vector<cv::Scalar> kCycle{kBlue,   kOrange,  kGreen, kVermillion,
                                     kPurple, kSkyBlue, kYellow};

struct Style {
  cv::Scalar color = kBlack;
  int dash = 0;  ///< 0 solid, 1 dashed, 2 dotted
  int thickness = 2;
};

Style methodStyle(size_t i) {
  return {kCycle[i % kCycle.size()], static_cast<int>((i / kCycle.size()) % 3), 2};
}

enum class Marker { kLine, kDot, kCircle, kCross, kTriangle, kSquare };

const int kFont = cv::FONT_HERSHEY_SIMPLEX;
const double kFontScale = 0.45;

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = kFontScale,
          cv::Scalar color = kBlack, int thickness = 1) {
  cv::putText(img, s, at, kFont, scale, color, thickness, cv::LINE_AA);
}

cv::Size textSize(const std::string& s, double scale = kFontScale, int thickness = 1) {
  int base = 0;
  return cv::getTextSize(s, kFont, scale, thickness, &base);
}

// 1, 2 or 5 times a power of ten, near range / target.
double niceStep(double range, int target) {
  const double raw = range / std::max(1, target);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double r = raw / mag;
  return (r < 1.5 ? 1.0 : r < 3.0 ? 2.0 : r < 7.0 ? 5.0 : 10.0) * mag;
}

std::string tickLabel(double v, double step) {
  char buf[32];
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  std::snprintf(buf, sizeof buf, "%.*f", decimals, std::abs(v) < step * 1e-6 ? 0.0 : v);
  return buf;
}

void drawMarker(cv::Mat& img, cv::Point p, Marker m, cv::Scalar color, int size = 4) {
  switch (m) {
    case Marker::kLine:
    case Marker::kDot:
      cv::circle(img, p, 1, color, cv::FILLED, cv::LINE_AA);
      break;
    case Marker::kCircle:
      cv::circle(img, p, size - 1, color, cv::FILLED, cv::LINE_AA);
      break;
    case Marker::kCross:
      cv::line(img, p + cv::Point(-size, -size), p + cv::Point(size, size), color, 2, cv::LINE_AA);
      cv::line(img, p + cv::Point(-size, size), p + cv::Point(size, -size), color, 2, cv::LINE_AA);
      break;
    case Marker::kTriangle: {
      const std::vector<cv::Point> tri{p + cv::Point(0, -size - 1), p + cv::Point(size, size),
                                       p + cv::Point(-size, size)};
      cv::fillConvexPoly(img, tri, color, cv::LINE_AA);
      break;
    }
    case Marker::kSquare:
      cv::rectangle(img, p - cv::Point(size - 1, size - 1), p + cv::Point(size - 1, size - 1),
                    color, cv::FILLED);
      break;
  }
}

// A chart: a plot area with a data range, axes with ticks and units, lines, markers and a
// legend to the right. It draws into `img`, which may be a region of a larger picture.
class Chart {
 public:
  Chart(cv::Mat img, bool legend) : img_(std::move(img)) {
    const int right = legend ? 250 : 20;
    plot_ =
        cv::Rect(78, 34, std::max(10, img_.cols - 78 - right), std::max(10, img_.rows - 34 - 52));
  }

  // The data range; with `equal`, one metre is as long on both axes (the range grows to fit).
  void setRange(double x0, double x1, double y0, double y1, bool equal = false) {
    if (!(x1 > x0)) x1 = x0 + 1.0;
    if (!(y1 > y0)) y1 = y0 + 1.0;
    if (equal) {
      const double sx = plot_.width / (x1 - x0), sy = plot_.height / (y1 - y0);
      const double s = std::min(sx, sy);
      const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
      const double hx = 0.5 * plot_.width / s, hy = 0.5 * plot_.height / s;
      x0 = cx - hx, x1 = cx + hx, y0 = cy - hy, y1 = cy + hy;
    }
    x0_ = x0, x1_ = x1, y0_ = y0, y1_ = y1;
  }

  cv::Point2d toPixel(double x, double y) const {
    return {plot_.x + (x - x0_) / (x1_ - x0_) * plot_.width,
            plot_.y + plot_.height - (y - y0_) / (y1_ - y0_) * plot_.height};
  }
  cv::Point pixel(double x, double y) const {
    const cv::Point2d p = toPixel(x, y);
    auto clampInt = [](double v) { return static_cast<int>(std::clamp(v, -1e6, 1e6)); };
    return {clampInt(std::round(p.x)), clampInt(std::round(p.y))};
  }
  double metresPerPixel() const { return (x1_ - x0_) / plot_.width; }

  // Fills the plot area from a function of the world point (grey level, or -1 for white).
  template <class Fn>
  void background(Fn grey) {
    for (int py = plot_.y; py < plot_.y + plot_.height; ++py)
      for (int px = plot_.x; px < plot_.x + plot_.width; ++px) {
        const double x = x0_ + (px + 0.5 - plot_.x) / plot_.width * (x1_ - x0_);
        const double y = y0_ + (plot_.y + plot_.height - py - 0.5) / plot_.height * (y1_ - y0_);
        const int g = grey(x, y);
        if (g >= 0) img_.at<cv::Vec3b>(py, px) = cv::Vec3b(g, g, g);
      }
  }

  void axes(const std::string& title, const std::string& xlabel, const std::string& ylabel,
            bool grid = true) {
    const double sx = niceStep(x1_ - x0_, std::max(2, plot_.width / 110));
    const double sy = niceStep(y1_ - y0_, std::max(3, plot_.height / 50));
    for (double v = std::ceil(x0_ / sx) * sx; v <= x1_ + 1e-9 * sx; v += sx) {
      const int px = pixel(v, y0_).x;
      if (grid) cv::line(img_, {px, plot_.y}, {px, plot_.y + plot_.height}, {228, 228, 228}, 1);
      cv::line(img_, {px, plot_.y + plot_.height}, {px, plot_.y + plot_.height + 5}, kBlack, 1);
      const std::string l = tickLabel(v, sx);
      text(img_, l, {px - textSize(l).width / 2, plot_.y + plot_.height + 19});
    }
    for (double v = std::ceil(y0_ / sy) * sy; v <= y1_ + 1e-9 * sy; v += sy) {
      const int py = pixel(x0_, v).y;
      if (grid) cv::line(img_, {plot_.x, py}, {plot_.x + plot_.width, py}, {228, 228, 228}, 1);
      cv::line(img_, {plot_.x - 5, py}, {plot_.x, py}, kBlack, 1);
      const std::string l = tickLabel(v, sy);
      text(img_, l, {plot_.x - 8 - textSize(l).width, py + 5});
    }
    cv::rectangle(img_, plot_, kBlack, 1);
    text(img_, title, {plot_.x, plot_.y - 12}, 0.55, kBlack, 1);
    const cv::Size xs = textSize(xlabel);
    text(img_, xlabel, {plot_.x + (plot_.width - xs.width) / 2, plot_.y + plot_.height + 40});
    // The y label, turned a quarter to the left.
    const cv::Size ys = textSize(ylabel);
    cv::Mat label(ys.height + 8, ys.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
    text(label, ylabel, {2, ys.height + 2});
    cv::rotate(label, label, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int lx = 6, ly = plot_.y + (plot_.height - label.rows) / 2;
    if (ly >= 0 && ly + label.rows <= img_.rows && lx + label.cols <= img_.cols)
      label.copyTo(img_(cv::Rect(lx, ly, label.cols, label.rows)));
  }

  // A polyline in data coordinates, broken at NaN, clipped to the plot area.
  void line(const std::vector<double>& xs, const std::vector<double>& ys, const Style& style) {
    cv::Point prev;
    bool have = false;
    double run = 0.0;  // pixels along the line, for the dash pattern
    for (size_t i = 0; i < xs.size(); ++i) {
      if (!std::isfinite(xs[i]) || !std::isfinite(ys[i])) {
        have = false;
        continue;
      }
      const cv::Point p = pixel(xs[i], ys[i]);
      if (!have) {
        prev = p;
        have = true;
        continue;
      }
      if (std::abs(p.x - prev.x) + std::abs(p.y - prev.y) < 2 && i + 1 < xs.size()) continue;
      segment(prev, p, style, run);
      prev = p;
    }
  }

  void markers(const std::vector<double>& xs, const std::vector<double>& ys, Marker m,
               cv::Scalar color, int size = 4, bool clamp_y = false) {
    for (size_t i = 0; i < xs.size(); ++i) {
      if (!std::isfinite(xs[i]) || !std::isfinite(ys[i])) continue;
      cv::Point p = pixel(xs[i], ys[i]);
      if (clamp_y) p.y = std::clamp(p.y, plot_.y + 1, plot_.y + plot_.height - 1);
      if (plot_.contains(p)) drawMarker(img_, p, m, color, size);
    }
  }

  // A bar of a round length at the bottom left of the plot, labelled in metres.
  void scaleBar() {
    const double len = niceStep(0.25 * (x1_ - x0_), 1);
    const cv::Point a(plot_.x + 16, plot_.y + plot_.height - 16);
    const cv::Point b(a.x + static_cast<int>(std::round(len / metresPerPixel())), a.y);
    cv::rectangle(img_, a - cv::Point(6, 22), b + cv::Point(6, 6), {255, 255, 255}, cv::FILLED);
    cv::line(img_, a, b, kBlack, 3);
    cv::line(img_, a - cv::Point(0, 5), a + cv::Point(0, 5), kBlack, 2);
    cv::line(img_, b - cv::Point(0, 5), b + cv::Point(0, 5), kBlack, 2);
    text(img_, tickLabel(len, len) + " m", {a.x, a.y - 8});
  }

  void legend(const std::string& label, const Style& style, Marker m = Marker::kLine) {
    legend_.push_back({label, style, m});
  }

  // Draws the legend entries to the right of the plot (as many as fit).
  void finish() {
    int y = plot_.y + 8;
    const int x = plot_.x + plot_.width + 14;
    for (const auto& [label, style, m] : legend_) {
      if (y + 6 > img_.rows) break;
      if (m == Marker::kLine) {
        double run = 0.0;
        segment({x, y}, {x + 26, y}, style, run, false);
      } else {
        drawMarker(img_, {x + 13, y}, m, style.color);
      }
      std::string l = label;
      while (l.size() > 4 && x + 34 + textSize(l).width > img_.cols - 4)
        l = l.substr(0, l.size() - 4) + "..";
      text(img_, l, {x + 34, y + 5});
      y += 18;
    }
  }

  const cv::Rect& plot() const { return plot_; }

 private:
  // A piece of line; data lines are clipped to the plot area, legend samples are not.
  void segment(cv::Point a, cv::Point b, const Style& style, double& run, bool clip = true) {
    const cv::Rect area(plot_.x, plot_.y, plot_.width + 1, plot_.height + 1);
    cv::Point ca = a, cb = b;
    if (clip && !cv::clipLine(area, ca, cb)) return;
    if (style.dash == 0) {
      cv::line(img_, ca, cb, style.color, style.thickness, cv::LINE_AA);
      return;
    }
    const double on = style.dash == 1 ? 9.0 : 2.5, period = style.dash == 1 ? 14.0 : 6.0;
    const double len = std::hypot(cb.x - ca.x, cb.y - ca.y);
    for (double s = 0.0; s < len; s += 1.0) {
      const double phase = std::fmod(run + s, period);
      if (phase >= on) continue;
      const double e = std::min(len, s + std::min(1.0, on - phase));
      const cv::Point2d d(cb.x - ca.x, cb.y - ca.y);
      cv::line(img_, cv::Point(ca) + cv::Point(d * (s / len)),
               cv::Point(ca) + cv::Point(d * (e / len)), style.color, style.thickness, cv::LINE_AA);
    }
    run += len;
  }

  cv::Mat img_;
  cv::Rect plot_;
  double x0_ = 0, x1_ = 1, y0_ = 0, y1_ = 1;
  std::vector<std::tuple<std::string, Style, Marker>> legend_;
};

cv::Mat canvas(int w, int h) { return cv::Mat(h, w, CV_8UC3, cv::Scalar(255, 255, 255)); }

void save(const fs::path& path, const cv::Mat& img) {
  std::vector<uchar> png;
  if (!cv::imencode(".png", img, png))
    throw data::InputError(path.string() + ": cannot encode the picture");
  data::writeFileAtomic(path.string(), std::string(png.begin(), png.end()));
}

// The extent of the reference, the anchors and the estimates (a method that flew off is not
// allowed to shrink the others: estimates count only within 3x the reference's extent).
loc::Rect worldExtent(const data::Dataset& ds, const std::vector<MethodSummary>& methods) {
  loc::Rect r{1e300, 1e300, -1e300, -1e300};
  auto add = [&r](double x, double y) {
    r.xmin = std::min(r.xmin, x), r.xmax = std::max(r.xmax, x);
    r.ymin = std::min(r.ymin, y), r.ymax = std::max(r.ymax, y);
  };
  for (const auto& p : ds.ground_truth) add(p.pose.x(), p.pose.y());
  for (const auto& a : ds.anchors) add(a.position.x(), a.position.y());
  const bool have = r.xmax >= r.xmin;
  const loc::Rect core = r;
  const double w = have ? std::max(core.xmax - core.xmin, core.ymax - core.ymin) : 0.0;
  for (const auto& m : methods)
    for (const auto& e : m.trajectory) {
      if (!std::isfinite(e.pose.x()) || !std::isfinite(e.pose.y())) continue;
      if (have && (e.pose.x() < core.xmin - w || e.pose.x() > core.xmax + w ||
                   e.pose.y() < core.ymin - w || e.pose.y() > core.ymax + w))
        continue;
      add(e.pose.x(), e.pose.y());
    }
  if (!(r.xmax >= r.xmin)) r = {-1, -1, 1, 1};
  const double margin = 0.05 * std::max({r.xmax - r.xmin, r.ymax - r.ymin, 1.0});
  return {r.xmin - margin, r.ymin - margin, r.xmax + margin, r.ymax + margin};
}

// The map (occupied dark, unknown light grey, free white) and the anchors under a trajectory.
void drawWorld(Chart& chart, const data::Dataset& ds) {
  if (ds.map) {
    const auto& map = *ds.map;
    const loc::Rect b = map.bounds();
    const double res = map.resolution();
    chart.background([&](double x, double y) {
      const int cx = static_cast<int>(std::floor((x - b.xmin) / res));
      const int cy = static_cast<int>(std::floor((y - b.ymin) / res));
      if (cx < 0 || cy < 0 || cx >= map.sizeX() || cy >= map.sizeY()) return -1;
      const float p = map.freeProbability(cx, cy);
      return p > 0.6f ? 255 : p < 0.4f ? 70 : 222;
    });
  }
}

void drawAnchors(Chart& chart, const data::Dataset& ds, cv::Mat& img) {
  for (const auto& a : ds.anchors) {
    const cv::Point p = chart.pixel(a.position.x(), a.position.y());
    if (!chart.plot().contains(p)) continue;
    drawMarker(img, p, Marker::kTriangle, kVermillion, 7);
    text(img, std::to_string(a.id), p + cv::Point(8, -6), 0.42, kVermillion);
  }
}

// One coordinate of every pose (reference or estimate).
template <class Pose>
std::vector<double> xsOf(const std::vector<Pose>& poses, int axis) {
  std::vector<double> out;
  out.reserve(poses.size());
  for (const auto& p : poses) out.push_back(p.pose[axis]);
  return out;
}

// A trajectory picture's canvas with the map drawn (drawn once, copied for every picture).
cv::Mat worldCanvas(const data::Dataset& ds, const loc::Rect& extent) {
  cv::Mat img = canvas(1100, 820);
  Chart chart(img, true);
  chart.setRange(extent.xmin, extent.xmax, extent.ymin, extent.ymax, true);
  drawWorld(chart, ds);
  return img;
}

void trajectoryPlot(const fs::path& path, const data::Dataset& ds, const cv::Mat& world,
                    const std::vector<const MethodSummary*>& shown,
                    const std::vector<size_t>& index, const loc::Rect& extent,
                    const std::string& title) {
  cv::Mat img = world.clone();
  Chart chart(img, true);
  chart.setRange(extent.xmin, extent.xmax, extent.ymin, extent.ymax, true);
  chart.axes(title, "x [m]", "y [m]");
  chart.scaleBar();  // under the lines and the anchors, which it must not hide
  if (!ds.ground_truth.empty()) chart.legend("reference", {kBlack, 0, 3});
  for (size_t k = 0; k < shown.size(); ++k) {
    const Style st = methodStyle(index[k]);
    chart.line(xsOf(shown[k]->trajectory, 0), xsOf(shown[k]->trajectory, 1), st);
    chart.legend(shown[k]->spec, st);
  }
  // The reference on top, so that many methods cannot bury it.
  if (!ds.ground_truth.empty())
    chart.line(xsOf(ds.ground_truth, 0), xsOf(ds.ground_truth, 1), {kBlack, 0, 2});
  drawAnchors(chart, ds, img);
  if (!ds.anchors.empty()) chart.legend("anchor", {kVermillion, 0, 2}, Marker::kTriangle);
  chart.finish();
  save(path, img);
}

double startTime(const data::Dataset& ds) {
  if (std::isfinite(ds.start_time) && (!ds.events.empty() || ds.ground_truth.empty()))
    return ds.start_time;
  return ds.ground_truth.empty() ? 0.0 : ds.ground_truth.front().t;
}

void errorPlot(const fs::path& path, const data::Dataset& ds, const MethodSummary& m,
               const Style& style) {
  const auto errors = associate(m.trajectory, ds.ground_truth, ds.manifest.gt_max_gap);
  const double t0 = startTime(ds);
  std::vector<double> t, e;
  double emax = 0.0;
  for (const auto& s : errors) {
    // A gap in the association breaks the line instead of bridging it.
    if (!t.empty() && s.t - t0 - t.back() > std::max(2.0, ds.manifest.gt_max_gap)) {
      t.push_back(NAN);
      e.push_back(NAN);
    }
    t.push_back(s.t - t0);
    e.push_back(s.e2d);
    emax = std::max(emax, s.e2d);
  }
  cv::Mat img = canvas(1000, 420);
  Chart chart(img, true);
  const double t1 = std::max(ds.duration(), t.empty() ? 1.0 : t.back());
  chart.setRange(0.0, std::max(1.0, t1), 0.0, std::max(0.05, 1.08 * emax));
  chart.axes("Planar error over time: " + m.spec, "time since start [s]", "error [m]");
  chart.line(t, e, style);
  chart.legend(m.spec, style);
  char rmse[64];
  std::snprintf(rmse, sizeof rmse, "RMSE %.3f m", m.metrics.rmse_2d);
  chart.legend(std::isfinite(m.metrics.rmse_2d) ? rmse : "no estimate scored", {kGrey, 1, 1});
  if (std::isfinite(m.metrics.rmse_2d))
    chart.line({0.0, t1}, {m.metrics.rmse_2d, m.metrics.rmse_2d}, {kGrey, 1, 1});
  chart.finish();
  save(path, img);
}

void cdfPlot(const fs::path& path, const data::Dataset& ds,
             const std::vector<MethodSummary>& methods) {
  std::vector<std::vector<double>> sorted;
  double p95max = 0.0;
  for (const auto& m : methods) {
    std::vector<double> e;
    for (const auto& s : associate(m.trajectory, ds.ground_truth, ds.manifest.gt_max_gap))
      e.push_back(s.e2d);
    std::sort(e.begin(), e.end());
    if (!e.empty()) p95max = std::max(p95max, quantile(e, 0.95));
    sorted.push_back(std::move(e));
  }
  cv::Mat img = canvas(1000, 620);
  Chart chart(img, true);
  chart.setRange(0.0, std::max(0.05, 1.1 * p95max), 0.0, 1.0);
  chart.axes("Error CDF (x up to 1.1 x the worst 95th percentile)", "planar error [m]",
             "fraction of estimates <= error");
  for (size_t i = 0; i < methods.size(); ++i) {
    const auto& e = sorted[i];
    if (e.empty()) continue;
    std::vector<double> xs, ys;
    const size_t step = std::max<size_t>(1, e.size() / 2000);
    for (size_t k = 0; k < e.size(); k += step) {
      xs.push_back(e[k]);
      ys.push_back(static_cast<double>(k + 1) / static_cast<double>(e.size()));
    }
    xs.push_back(e.back());
    ys.push_back(1.0);
    chart.line(xs, ys, methodStyle(i));
    chart.legend(methods[i].spec, methodStyle(i));
  }
  chart.finish();
  save(path, img);
}

// What a method did with each range: a category (its label) per range, each drawn with its own
// marker. The judge is the first method that records its NLOS decisions (the particle filters),
// else the first that records its front end's rejections.
struct RangeFates {
  const MethodSummary* judge = nullptr;
  std::vector<std::string> labels;                         ///< in drawing order (the rarest on top)
  std::map<std::tuple<double, int, double>, size_t> fate;  ///< (t, anchor, range) -> label index
  size_t fallback = 0;  ///< the label of a range the judge has no record of
};

RangeFates rangeFates(const std::vector<MethodSummary>& methods) {
  RangeFates f;
  for (const auto& m : methods)
    if (!m.range_decisions.empty()) {
      f.judge = &m;
      break;
    }
  if (!f.judge)
    for (const auto& m : methods)
      if (!m.range_rejections.empty()) {
        f.judge = &m;
        break;
      }
  auto label = [&f](const std::string& l) {
    const auto it = std::find(f.labels.begin(), f.labels.end(), l);
    if (it != f.labels.end()) return static_cast<size_t>(it - f.labels.begin());
    f.labels.push_back(l);
    return f.labels.size() - 1;
  };
  if (!f.judge) {
    f.fallback = label("range (no method judged it)");
    return f;
  }
  const bool decides = !f.judge->range_decisions.empty();
  f.fallback = label(decides ? "not used by the filter" : "accepted by the front end");
  if (decides) {
    const size_t used = label("used"), pose = label("NLOS: pose test"),
                 ray = label("NLOS: ray-cast"), gated = label("not used by the filter");
    for (const auto& d : f.judge->range_decisions)
      f.fate[{d.t, d.anchor_id, d.range}] = d.used           ? used
                                            : d.flag_pose    ? pose
                                            : d.flag_raycast ? ray
                                                             : gated;
  }
  for (const auto& r : f.judge->range_rejections)
    f.fate[{r.t, r.anchor_id, r.range}] = label(r.reason);
  return f;
}

bool residualPlot(const fs::path& path, const data::Dataset& ds,
                  const std::vector<MethodSummary>& methods, std::string& caption) {
  if (ds.ground_truth.empty() || ds.anchors.empty()) return false;
  const RangeFates fates = rangeFates(methods);
  struct Point {
    double t, residual;
    size_t fate;
  };
  std::map<int, std::vector<Point>> by_anchor;
  const double t0 = startTime(ds);
  for (const auto& ev : ds.events) {
    const auto* r = std::get_if<uwb::Range>(&ev);
    if (!r || !r->on_robot) continue;
    const uwb::Anchor* a = uwb::findAnchor(ds.anchors, r->anchor_id);
    const auto truth = interpolateGroundTruth(ds.ground_truth, r->t, ds.manifest.gt_max_gap);
    if (!a || !truth) continue;
    const auto it = fates.fate.find({r->t, r->anchor_id, r->range});
    by_anchor[r->anchor_id].push_back(
        {r->t - t0, r->range - uwb::predictRange(*truth, r->tag_on_robot, a->position),
         it == fates.fate.end() ? fates.fallback : it->second});
  }
  if (by_anchor.empty()) return false;
  // Markers and colours by category: what was used (or merely accepted) small blue dots, the
  // judge's unrecorded ranges grey circles, every rejection or NLOS verdict its own shape.
  const std::vector<std::pair<Marker, cv::Scalar>> looks{
      {Marker::kCross, kVermillion}, {Marker::kTriangle, kOrange},  {Marker::kSquare, kPurple},
      {Marker::kCross, kGreen},      {Marker::kTriangle, kSkyBlue}, {Marker::kSquare, kBlack},
      {Marker::kCross, kYellow}};
  std::vector<std::pair<Marker, cv::Scalar>> looked(fates.labels.size());
  for (size_t f = 0, other = 0; f < fates.labels.size(); ++f) {
    const std::string& l = fates.labels[f];
    if (l == "used" || l == "accepted by the front end" || l == "range (no method judged it)")
      looked[f] = {Marker::kDot, kBlue};
    else if (f == fates.fallback)
      looked[f] = {Marker::kCircle, kGrey};
    else
      looked[f] = looks[other++ % looks.size()];
  }
  auto look = [&](size_t f) { return looked[f]; };
  std::vector<long> total(fates.labels.size(), 0);  // the legend lists what occurs
  for (const auto& [anchor, points] : by_anchor)
    for (const auto& p : points) ++total[p.fate];
  const size_t panels = std::min<size_t>(by_anchor.size(), 12);
  const int panel_h = 190;
  cv::Mat img = canvas(1100, static_cast<int>(panels) * panel_h + 10);
  size_t k = 0;
  const double t1 = std::max(1.0, ds.duration());
  for (const auto& [anchor, points] : by_anchor) {
    if (k == panels) break;
    std::vector<double> res;
    for (const auto& p : points) res.push_back(p.residual);
    // The middle 98 % sets the scale; the rest is drawn at the edge.
    const double lo = std::min(-0.3, quantile(res, 0.01)), hi = std::max(0.3, quantile(res, 0.99));
    Chart chart(img(cv::Rect(0, static_cast<int>(k) * panel_h, img.cols, panel_h)), k == 0);
    const double pad = 0.08 * (hi - lo);
    chart.setRange(0.0, t1, lo - pad, hi + pad);
    chart.axes("Anchor " + std::to_string(anchor) + ": range - distance from the reference",
               k + 1 == panels ? "time since start [s]" : "", "residual [m]");
    // The common categories first, so that the rare ones are drawn over them.
    std::vector<size_t> order(fates.labels.size());
    std::vector<size_t> count(fates.labels.size(), 0);
    for (const auto& p : points) ++count[p.fate];
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t a, size_t b) { return count[a] > count[b]; });
    for (size_t f : order) {
      std::vector<double> xs, ys;
      for (const auto& p : points)
        if (p.fate == f) xs.push_back(p.t), ys.push_back(p.residual);
      const auto [marker, colour] = look(f);
      chart.markers(xs, ys, marker, colour, marker == Marker::kDot ? 2 : 4, true);
    }
    if (k == 0)
      for (size_t f = 0; f < fates.labels.size(); ++f)
        if (total[f] > 0)
          chart.legend(fates.labels[f] + " (" + std::to_string(total[f]) + ")",
                       {look(f).second, 0, 2}, look(f).first);
    chart.line({0.0, t1}, {0.0, 0.0}, {kBlack, 1, 1});
    chart.finish();
    ++k;
  }
  save(path, img);
  caption = "Range residuals (range minus the distance from the reference pose) per anchor";
  caption += fates.judge ? ", marked by what " + fates.judge->spec +
                               " did with each range (used; NLOS by its LiDAR-pose test or map "
                               "ray-cast; or rejected by its front end, by reason)"
                         : "; no method recorded what it did with them";
  if (by_anchor.size() > panels) caption += " (the first 12 anchors)";
  return true;
}

bool swarmPlot(const fs::path& path, const data::Dataset& ds,
               const std::vector<MethodSummary>& methods) {
  cv::Mat img = canvas(1000, 420);
  Chart chart(img, true);
  std::vector<std::tuple<size_t, std::vector<double>, std::vector<double>>> series;
  double ymax = 0.0;
  const double t0 = startTime(ds);
  for (size_t i = 0; i < methods.size(); ++i)
    for (const auto& [suffix, contents] : methods[i].artifacts) {
      if (suffix != "swarm_spread.csv") continue;
      std::istringstream in(contents);
      std::string line;
      std::getline(in, line);  // header
      std::vector<double> t, s;
      while (std::getline(in, line)) {
        double a = 0, b = 0;
        if (std::sscanf(line.c_str(), "%lf,%lf", &a, &b) != 2) continue;
        t.push_back(a - t0);
        s.push_back(b);
        ymax = std::max(ymax, b);
      }
      series.emplace_back(i, std::move(t), std::move(s));
    }
  if (series.empty()) return false;
  chart.setRange(0.0, std::max(1.0, ds.duration()), 0.0, std::max(0.01, 1.08 * ymax));
  chart.axes("PF-IBAS swarm spread over time", "time since start [s]", "spread (xy std) [m]");
  for (const auto& [i, t, s] : series) {
    chart.line(t, s, methodStyle(i));
    chart.legend(methods[i].spec, methodStyle(i));
  }
  chart.finish();
  save(path, img);
  return true;
}

}  // namespace

std::vector<PlotFile> writePlots(const std::string& plots_dir, const data::Dataset& dataset,
                                 const std::vector<MethodSummary>& methods, int jobs) {
  const fs::path dir(plots_dir);
  data::ensureDirectory(dir.string());
  const loc::Rect extent = worldExtent(dataset, methods);
  const std::string world = dataset.map ? "on the map" : "on a blank grid (no map)";
  // The map canvas is drawn once, by the first picture that needs it; meanwhile the other
  // threads draw the pictures without a map.
  std::once_flag canvas_drawn;
  cv::Mat world_canvas_storage;
  auto world_canvas = [&]() -> const cv::Mat& {
    std::call_once(canvas_drawn, [&] { world_canvas_storage = worldCanvas(dataset, extent); });
    return world_canvas_storage;
  };
  // Each picture is a task; they are listed in this order, and run on `jobs` threads in the
  // order of `run_order`: first the picture of every method, then those without a map, then
  // the rest.
  using Task = std::function<std::optional<PlotFile>()>;
  std::vector<Task> tasks;
  std::vector<size_t> on_map;
  tasks.push_back([&]() -> std::optional<PlotFile> {
    std::vector<const MethodSummary*> all;
    std::vector<size_t> index;
    for (size_t i = 0; i < methods.size(); ++i) all.push_back(&methods[i]), index.push_back(i);
    trajectoryPlot(dir / "trajectories.png", dataset, world_canvas(), all, index, extent,
                   "Trajectories " + world + ": " + dataset.name);
    return PlotFile{"trajectories.png", "The reference and every method " + world};
  });
  if (!dataset.ground_truth.empty())
    tasks.push_back([&]() -> std::optional<PlotFile> {
      cdfPlot(dir / "error_cdf.png", dataset, methods);
      return PlotFile{"error_cdf.png", "Planar error CDF, every method"};
    });
  tasks.push_back([&]() -> std::optional<PlotFile> {
    std::string caption;
    if (!residualPlot(dir / "range_residuals.png", dataset, methods, caption)) return {};
    return PlotFile{"range_residuals.png", caption};
  });
  tasks.push_back([&]() -> std::optional<PlotFile> {
    if (!swarmPlot(dir / "swarm_spread.png", dataset, methods)) return {};
    return PlotFile{"swarm_spread.png",
                    "PF-IBAS swarm spread (std of the particles' xy) over time"};
  });
  for (size_t i = 0; i < methods.size(); ++i) {
    const std::string label = fileLabel(methods[i].spec);
    on_map.push_back(tasks.size());
    tasks.push_back([&, i, label]() -> std::optional<PlotFile> {
      trajectoryPlot(dir / ("trajectory_" + label + ".png"), dataset, world_canvas(), {&methods[i]},
                     {i}, extent, methods[i].spec + " " + world);
      return PlotFile{"trajectory_" + label + ".png", methods[i].spec + " and the reference"};
    });
    if (!dataset.ground_truth.empty())
      tasks.push_back([&, i, label]() -> std::optional<PlotFile> {
        errorPlot(dir / ("error_" + label + ".png"), dataset, methods[i], methodStyle(i));
        return PlotFile{"error_" + label + ".png", methods[i].spec + ": planar error over time"};
      });
  }
  std::vector<bool> needs_map(tasks.size(), false);
  for (size_t k : on_map) needs_map[k] = true;
  std::vector<size_t> run_order{0};
  for (size_t k = 1; k < tasks.size(); ++k)
    if (!needs_map[k]) run_order.push_back(k);
  run_order.insert(run_order.end(), on_map.begin(), on_map.end());
  std::vector<std::optional<PlotFile>> done(tasks.size());
  parallelFor(tasks.size(), jobs, [&](size_t k) { done[run_order[k]] = tasks[run_order[k]](); });
  std::vector<PlotFile> out;
  for (auto& d : done)
    if (d) out.push_back(std::move(*d));
  return out;
}

}  // namespace uwbloc::eval
