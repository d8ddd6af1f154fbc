#include "data/chart.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace ii {

namespace {

std::vector<double> running_mean(const std::vector<double>& v, size_t window) {
  std::vector<double> out(v.size());
  double sum = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    sum += v[i];
    if (i >= window) sum -= v[i - window];
    out[i] = sum / double(std::min(i + 1, window));
  }
  return out;
}

}  // namespace

Image line_chart(const std::vector<double>& values, const std::string& title, int width, int height) {
  cv::Mat canvas(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 70, right = 20, top = 36, bottom = 40;
  const cv::Rect plot(left, top, width - left - right, height - top - bottom);
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar ink(40, 40, 40), grey(190, 190, 190), blue(200, 90, 40);  // B, G, R
  cv::putText(canvas, title, {left, 24}, font, 0.55, ink, 1, cv::LINE_AA);
  cv::rectangle(canvas, plot, ink);
  std::vector<double> finite;
  for (double v : values)
    if (std::isfinite(v)) finite.push_back(v);
  if (finite.size() == values.size() && !values.empty()) {
    const std::vector<double> mean = running_mean(values, std::max<size_t>(1, values.size() / 50));
    const auto [lo_it, hi_it] = std::minmax_element(mean.begin(), mean.end());
    double lo = *lo_it, hi = *hi_it;
    if (hi - lo < 1e-12) hi = lo + 1e-12;
    const double margin = 0.05 * (hi - lo);
    lo -= margin;
    hi += margin;
    auto point = [&](size_t i, double v) {
      const double x = values.size() > 1 ? double(i) / double(values.size() - 1) : 0.5;
      const double y = std::clamp((v - lo) / (hi - lo), 0.0, 1.0);
      return cv::Point(plot.x + int(std::lround(x * (plot.width - 1))),
                       plot.y + plot.height - 1 - int(std::lround(y * (plot.height - 1))));
    };
    for (size_t i = 0; i < values.size(); ++i) cv::circle(canvas, point(i, values[i]), 0, grey, -1);
    std::vector<cv::Point> line;
    for (size_t i = 0; i < mean.size(); ++i) line.push_back(point(i, mean[i]));
    cv::polylines(canvas, line, false, blue, 2, cv::LINE_AA);
    cv::putText(canvas, fmt::format("{:.4f}", hi), {4, plot.y + 12}, font, 0.4, ink, 1, cv::LINE_AA);
    cv::putText(canvas, fmt::format("{:.4f}", lo), {4, plot.y + plot.height}, font, 0.4, ink, 1, cv::LINE_AA);
    cv::putText(canvas, fmt::format("step 1, mean {:.4f}", mean.front()), {plot.x, height - 14}, font, 0.45, ink, 1,
                cv::LINE_AA);
    const std::string end = fmt::format("step {}, mean {:.4f}", values.size(), mean.back());
    int base = 0;
    const cv::Size size = cv::getTextSize(end, font, 0.45, 1, &base);
    cv::putText(canvas, end, {plot.x + plot.width - size.width, height - 14}, font, 0.45, ink, 1, cv::LINE_AA);
  }
  Image out(width, height, 3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const cv::Vec3b p = canvas.at<cv::Vec3b>(y, x);  // drawn as B, G, R
      for (int c = 0; c < 3; ++c) out.at(y, x, c) = p[2 - c] / 255.f;
    }
  return out;
}

}  // namespace ii
