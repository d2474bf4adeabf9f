#include "core/eval/trajectory_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/common/error.h"

namespace orbatlas {
namespace {

const cv::Scalar kGroundTruthColour(40, 40, 40);  // BGR: near black
// The estimates' colours, in turn (BGR): red, blue, green, orange, purple, teal.
const cv::Scalar kEstimateColours[] = {{30, 30, 220}, {200, 90, 20},  {40, 160, 40},
                                       {0, 140, 255}, {160, 50, 140}, {150, 150, 0}};
constexpr int kDashPx = 10, kGapPx = 7;
const cv::Scalar kGridColour(225, 225, 225);
const cv::Scalar kTextColour(0, 0, 0);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kShift = 4;  // sub-pixel bits for anti-aliased polylines

// 1, 2 or 5 times a power of ten, giving about `target` ticks over `span`.
double nice_step(double span, double target) {
  const double raw = span / target;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0, 10.0})
    if (m * magnitude >= raw) return m * magnitude;
  return 10.0 * magnitude;
}

std::string tick_label(double value, double step) {
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, std::abs(value) < step * 1e-6 ? 0.0 : value);
  return buf;
}

// Metres -> pixels with one scale for both axes (equal aspect), y up.
struct View {
  cv::Rect area;
  double centre_x = 0, centre_y = 0, px_per_m = 1;
  cv::Point2d to_px(double x, double y) const {
    return {area.x + area.width / 2.0 + (x - centre_x) * px_per_m,
            area.y + area.height / 2.0 - (y - centre_y) * px_per_m};
  }
  double x_min() const { return centre_x - area.width / 2.0 / px_per_m; }
  double x_max() const { return centre_x + area.width / 2.0 / px_per_m; }
  double y_min() const { return centre_y - area.height / 2.0 / px_per_m; }
  double y_max() const { return centre_y + area.height / 2.0 / px_per_m; }
};

View make_view(const TrajectoryPlot& plot, const cv::Rect& area) {
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  std::vector<const std::vector<Eigen::Vector3d>*> lines;
  for (const auto& g : plot.ground_truth) lines.push_back(&g);
  for (const PlotLine& e : plot.estimates) lines.push_back(&e.points);
  for (const auto* points : lines)
    for (const Eigen::Vector3d& p : *points) {
      if (!std::isfinite(p.x()) || !std::isfinite(p.y())) continue;
      x0 = std::min(x0, p.x());
      x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y());
      y1 = std::max(y1, p.y());
    }
  ORBATLAS_CHECK(x0 <= x1 && y0 <= y1, "trajectory plot: no finite positions to draw");
  const double span = std::max({x1 - x0, y1 - y0, 0.1});
  const double pad = 0.05 * span;  // margin around the data
  View v;
  v.area = area;
  v.centre_x = 0.5 * (x0 + x1);
  v.centre_y = 0.5 * (y0 + y1);
  v.px_per_m = std::min(area.width / (x1 - x0 + 2 * pad + 1e-12), area.height / (y1 - y0 + 2 * pad + 1e-12));
  v.px_per_m = std::min(v.px_per_m, area.width / 0.1);
  return v;
}

cv::Point fixed_point(const cv::Point2d& p) {
  constexpr double k = 1 << kShift;
  return {static_cast<int>(std::lround(p.x * k)), static_cast<int>(std::lround(p.y * k))};
}

void draw_grid(cv::Mat& img, const View& v) {
  const double step = nice_step(std::max(v.x_max() - v.x_min(), v.y_max() - v.y_min()), 10.0);
  const double font_scale = 0.45;
  const cv::Rect& a = v.area;
  for (double x = std::ceil(v.x_min() / step) * step; x <= v.x_max(); x += step) {
    const int px = static_cast<int>(std::lround(v.to_px(x, 0).x));
    cv::line(img, {px, a.y}, {px, a.y + a.height}, kGridColour, 1);
    cv::line(img, {px, a.y + a.height}, {px, a.y + a.height + 6}, kTextColour, 1);
    const std::string label = tick_label(x, step);
    int base = 0;
    const cv::Size size = cv::getTextSize(label, kFont, font_scale, 1, &base);
    cv::putText(img, label, {px - size.width / 2, a.y + a.height + 10 + size.height}, kFont, font_scale, kTextColour, 1,
                cv::LINE_AA);
  }
  for (double y = std::ceil(v.y_min() / step) * step; y <= v.y_max(); y += step) {
    const int py = static_cast<int>(std::lround(v.to_px(0, y).y));
    cv::line(img, {a.x, py}, {a.x + a.width, py}, kGridColour, 1);
    cv::line(img, {a.x - 6, py}, {a.x, py}, kTextColour, 1);
    const std::string label = tick_label(y, step);
    int base = 0;
    const cv::Size size = cv::getTextSize(label, kFont, font_scale, 1, &base);
    cv::putText(img, label, {a.x - 10 - size.width, py + size.height / 2}, kFont, font_scale, kTextColour, 1,
                cv::LINE_AA);
  }
  cv::rectangle(img, a, kTextColour, 1);
  int base = 0;
  const cv::Size xs = cv::getTextSize("x [m]", kFont, 0.55, 1, &base);
  cv::putText(img, "x [m]", {a.x + a.width / 2 - xs.width / 2, a.y + a.height + 48}, kFont, 0.55, kTextColour, 1,
              cv::LINE_AA);
  cv::putText(img, "y [m]", {a.x - 60, a.y - 10}, kFont, 0.55, kTextColour, 1, cv::LINE_AA);
}

std::vector<cv::Point2d> pixels(const View& v, const std::vector<Eigen::Vector3d>& points) {
  std::vector<cv::Point2d> out;
  out.reserve(points.size());
  for (const Eigen::Vector3d& p : points)
    if (std::isfinite(p.x()) && std::isfinite(p.y())) out.push_back(v.to_px(p.x(), p.y()));
  return out;
}

void draw_path(cv::Mat& img, const View& v, const std::vector<Eigen::Vector3d>& points, const cv::Scalar& colour) {
  std::vector<cv::Point> line;
  for (const cv::Point2d& p : pixels(v, points)) line.push_back(fixed_point(p));
  if (line.empty()) return;
  cv::polylines(img, line, false, colour, 2, cv::LINE_AA, kShift);
  cv::circle(img, line.front(), 5 << kShift, colour, 2, cv::LINE_AA, kShift);  // start marker
}

// Dashes of kDashPx with gaps of kGapPx along the polyline, continuing across its vertices.
void draw_dashed(cv::Mat& img, const View& v, const std::vector<Eigen::Vector3d>& points, const cv::Scalar& colour) {
  const std::vector<cv::Point2d> line = pixels(v, points);
  double phase = 0.0;  // along the current dash-and-gap period
  for (std::size_t i = 1; i < line.size(); ++i) {
    const cv::Point2d a = line[i - 1], d = line[i] - line[i - 1];
    const double length = std::hypot(d.x, d.y);
    double at = 0.0;
    while (at < length) {
      const bool on = phase < kDashPx;
      const double step = std::min(length - at, (on ? kDashPx : kDashPx + kGapPx) - phase);
      if (on && length > 0)
        cv::line(img, fixed_point(a + d * (at / length)), fixed_point(a + d * ((at + step) / length)), colour, 1,
                 cv::LINE_AA, kShift);
      at += step;
      phase += step;
      if (phase >= kDashPx + kGapPx) phase = 0.0;
    }
  }
}

void draw_legend(cv::Mat& img, const View& v, const TrajectoryPlot& plot) {
  const double font_scale = 0.5;
  struct Entry {
    const std::string* label;
    cv::Scalar colour;
    bool dashed;
  };
  std::vector<Entry> entries;
  if (!plot.ground_truth.empty()) entries.push_back({&plot.ground_truth_label, kGroundTruthColour, true});
  for (std::size_t i = 0; i < plot.estimates.size(); ++i)
    entries.push_back({&plot.estimates[i].label, kEstimateColours[i % std::size(kEstimateColours)], false});
  int base = 0, text_w = 0;
  for (const Entry& e : entries)
    text_w = std::max(text_w, cv::getTextSize(*e.label, kFont, font_scale, 1, &base).width);
  const int rows = static_cast<int>(entries.size());
  const cv::Rect box(v.area.x + v.area.width - text_w - 70, v.area.y + 10, text_w + 60, 8 + 22 * rows);
  cv::rectangle(img, box, cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(img, box, cv::Scalar(160, 160, 160), 1);
  int y = box.y + 18;
  for (const Entry& e : entries) {
    if (e.dashed) {
      for (int x = box.x + 8; x < box.x + 38; x += kDashPx + kGapPx)
        cv::line(img, {x, y - 4}, {std::min(x + kDashPx, box.x + 38), y - 4}, e.colour, 1, cv::LINE_AA);
    } else {
      cv::line(img, {box.x + 8, y - 4}, {box.x + 38, y - 4}, e.colour, 2, cv::LINE_AA);
    }
    cv::putText(img, *e.label, {box.x + 46, y}, kFont, font_scale, kTextColour, 1, cv::LINE_AA);
    y += 22;
  }
}

}  // namespace

PlotArea trajectory_plot_area(int width_px, int height_px) { return {90, 75, width_px - 90 - 30, height_px - 75 - 70}; }

void write_trajectory_plot(const std::filesystem::path& png, const TrajectoryPlot& plot) {
  ORBATLAS_CHECK(plot.width_px >= 300 && plot.height_px >= 300, "trajectory plot: image too small");
  ORBATLAS_CHECK(!plot.ground_truth.empty() || !plot.estimates.empty(), "trajectory plot: nothing to draw");
  cv::Mat img(plot.height_px, plot.width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  const PlotArea a = trajectory_plot_area(plot.width_px, plot.height_px);
  const cv::Rect area(a.x, a.y, a.width, a.height);
  const View view = make_view(plot, area);

  draw_grid(img, view);
  cv::Mat clip = img(area);  // paths stay inside the axes
  View local = view;
  local.area = cv::Rect(0, 0, area.width, area.height);
  for (const auto& g : plot.ground_truth) draw_dashed(clip, local, g, kGroundTruthColour);
  for (std::size_t i = 0; i < plot.estimates.size(); ++i)
    draw_path(clip, local, plot.estimates[i].points, kEstimateColours[i % std::size(kEstimateColours)]);
  draw_legend(img, view, plot);

  int base = 0;
  const cv::Size ts = cv::getTextSize(plot.title, kFont, 0.65, 1, &base);
  cv::putText(img, plot.title, {std::max(5, plot.width_px / 2 - ts.width / 2), 30}, kFont, 0.65, kTextColour, 1,
              cv::LINE_AA);

  bool ok = false;
  try {
    ok = cv::imwrite(png.string(), img);
  } catch (const cv::Exception& e) {
    throw Error("cannot write plot " + png.string() + ": " + e.what());
  }
  ORBATLAS_CHECK(ok, "cannot write plot " << png.string());
}

}  // namespace orbatlas
