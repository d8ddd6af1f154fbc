#include "eval/report.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <fmt/core.h>
#include <opencv2/imgproc.hpp>

#include "common/files.h"
#include "data/image_ops.h"
#include "data/opencv_image.h"
#include "data/masks.h"

namespace ii {

nlohmann::json metric_json(double value) {
  if (std::isnan(value)) return nullptr;
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  return value;
}

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr int kSheetPanelWidth = 480;        // contact-sheet panels are scaled down to this width
constexpr float kErrorMapFullScale = 0.25f;  // mean absolute error shown as the top colour

std::string format_number(double v, int decimals) {
  if (std::isnan(v)) return "–";
  if (std::isinf(v)) return v > 0 ? "∞" : "−∞";
  return fmt::format("{:.{}f}", v, decimals);
}

std::string html_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

cv::Mat mask_to_u8(const Image& mask) {
  cv::Mat m(mask.height, mask.width, CV_8UC1);
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x) m.at<uint8_t>(y, x) = mask.at(y, x) > 0.5f ? 255 : 0;
  return m;
}

}  // namespace

// Mean absolute error over the channels, INFERNO colours (black = 0, yellow >= full scale).
Image error_map(const Image& a, const Image& b) {
  std::vector<uint8_t> levels(static_cast<size_t>(a.width) * a.height);
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      float e = 0;
      for (int c = 0; c < 3; ++c) e += std::abs(a.at(y, x, c) - b.at(y, x, c));
      levels[static_cast<size_t>(y) * a.width + x] =
          static_cast<uint8_t>(std::lround(std::min(e / 3.f / kErrorMapFullScale, 1.f) * 255.f));
    }
  return inferno_colours(levels, a.width, a.height);
}

Image with_mask_outline(const Image& image, const std::optional<Image>& mask) {
  cv::Mat bgr = to_bgr8(image);
  if (mask) {
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(mask_to_u8(*mask), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    const int thickness = std::max(1, image.height / 200);
    cv::drawContours(bgr, contours, -1, cv::Scalar(0, 0, 255), thickness);  // red
  }
  return from_bgr8(bgr);
}

// Panels side by side, each scaled to kSheetPanelWidth (never up), white gaps.
Image contact_sheet(const std::vector<Image>& panels) {
  const int gap = 4;
  std::vector<Image> scaled;
  for (const Image& p : panels) {
    const int w = std::min(p.width, kSheetPanelWidth);
    const int h = std::max(1, static_cast<int>(std::lround(double(p.height) * w / p.width)));
    scaled.push_back(w == p.width ? p : resize_area(p, w, h));
  }
  int width = gap * (static_cast<int>(scaled.size()) - 1), height = 0;
  for (const Image& p : scaled) {
    width += p.width;
    height = std::max(height, p.height);
  }
  Image sheet(width, height, 3, 1.f);
  int x0 = 0;
  for (const Image& p : scaled) {
    for (int y = 0; y < p.height; ++y)
      for (int x = 0; x < p.width; ++x)
        for (int c = 0; c < 3; ++c) sheet.at(y, x0 + x, c) = p.at(y, x, c);
    x0 += p.width + gap;
  }
  return sheet;
}

std::string metric_cell(const json& v, int decimals) {
  if (v.is_number()) return format_number(v.get<double>(), decimals);
  if (v.is_string()) return v.get<std::string>() == "inf" ? "∞" : html_escape(v.get<std::string>());
  return "–";
}

void write_eval_report(const fs::path& out, const json& metrics) {
  static const std::vector<std::pair<std::string, int>> columns = {
      {"psnr", 2}, {"ssim", 4}, {"masked_psnr", 2}, {"masked_ssim", 4}, {"outside_psnr", 2}, {"lpips", 4},
      {"masked_lpips", 4}};
  std::string h;
  h += "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>instainpaint eval: " +
       html_escape(metrics["scene"].get<std::string>()) + "</title>\n";
  h += "<style>body{font-family:sans-serif;margin:1.5em}table{border-collapse:collapse}td,th{padding:3px 8px;"
       "border-bottom:1px solid #ddd;text-align:right}th{background:#f4f4f4}img{max-width:100%}"
       ".view{margin:1.5em 0}.note{color:#666;font-size:90%}</style></head><body>\n";
  h += "<h1>" + html_escape(metrics["scene"].get<std::string>()) + "</h1>\n";
  h += "<p>method <b>" + html_escape(metrics["method"].get<std::string>()) + "</b>, " +
       std::to_string(metrics["views"].size()) + " test views at " +
       std::to_string(metrics["working_size"][0].get<int>()) + "×" +
       std::to_string(metrics["working_size"][1].get<int>()) +
       ", predictions quantised: " + html_escape(metrics["quantize"].get<std::string>()) + "</p>\n";
  h += "<h2>Summary</h2>\n<table><tr>";
  for (const auto& [key, d] : columns) h += "<th>" + key + "</th>";
  for (const char* key : {"fid", "kid", "c_fid", "c_kid"}) h += std::string("<th>") + key + "</th>";
  h += "</tr>\n<tr>";
  for (const auto& [key, d] : columns) h += "<td>" + metric_cell(metrics["mean"].value(key, json()), d) + "</td>";
  for (const char* key : {"fid", "kid", "c_fid", "c_kid"})
    h += "<td>" +
         metric_cell(metrics["set"].value(key, json()), std::string(key).find("kid") != std::string::npos ? 5 : 2) +
         "</td>";
  h += "</tr></table>\n";
  const json& rw = metrics.value("region_and_whole", json::object());
  if (rw.contains("psnr") && rw["psnr"].contains("region_minus_whole")) {
    h += "<p>The region against the whole image: PSNR " + metric_cell(rw["psnr"]["region"], 2) + " against " +
         metric_cell(rw["psnr"]["whole"], 2) + " (" + fmt::format("{:+.2f}", rw["psnr"]["region_minus_whole"].get<double>()) +
         " dB)";
    if (rw.contains("uncovered"))
      h += fmt::format("; the region's uncovered pixels (the background shows): {} in {} views",
                       rw["uncovered"]["pixels"].get<int64_t>(), rw["uncovered"]["views"].get<int>());
    h += "</p>\n";
  }
  const json protocol = metrics["prediction"].value("reference_protocol", json());
  if (protocol.is_object())
    h += "<p>Reference: the object-free test view <b>" + html_escape(protocol["view"].get<std::string>()) +
         "</b> (its own photo); it is not among the scored views.</p>\n";
  if (!metrics["unavailable"].empty()) {
    h += "<p class=\"note\">Unavailable:</p><ul class=\"note\">";
    for (const auto& [key, reason] : metrics["unavailable"].items())
      h += "<li><b>" + html_escape(key) + "</b>: " + html_escape(reason.get<std::string>()) + "</li>";
    h += "</ul>\n";
  }
  h += "<p class=\"note\">Each sheet: ground truth | prediction | error map (mean absolute error, black 0, yellow ≥ " +
       fmt::format("{:.2f}", kErrorMapFullScale) + ") | prediction with the mask outline (red).</p>\n";
  const json refine = metrics["prediction"].value("after_prediction", json::object()).value("refine", json::object());
  if (refine.contains("loss_chart"))
    h += "<h2>Refinement</h2>\n<p>" + html_escape(refine.value("length", std::string())) + ", " +
         std::to_string(refine.value("steps", 0)) + " steps</p><img src=\"" +
         html_escape(refine["loss_chart"].get<std::string>()) + "\" alt=\"refinement loss\">\n";
  h += "<h2>Views</h2>\n";
  for (const json& v : metrics["views"]) {
    h += "<div class=\"view\"><h3>" + html_escape(v["name"].get<std::string>()) + "</h3><table><tr>";
    for (const auto& [key, d] : columns) h += "<th>" + key + "</th>";
    h += "</tr><tr>";
    for (const auto& [key, d] : columns) h += "<td>" + metric_cell(v.value(key, json()), d) + "</td>";
    h += "</tr></table>\n<img src=\"" + html_escape(v["files"]["sheet"].get<std::string>()) + "\" alt=\"" +
         html_escape(v["name"].get<std::string>()) + "\"></div>\n";
  }
  h += "<h2>Where the time went</h2>\n<table><tr><th>stage</th><th>ms</th><th>calls</th></tr>";
  for (const json& s : metrics["stages"])
    h += fmt::format("<tr><th>{}{}</th><td>{:.0f}</td><td>{}</td></tr>", html_escape(s["stage"].get<std::string>()),
                     s.value("behind", false) ? " (behind)" : "", s["ms"].get<double>(), s["calls"].get<int>());
  h += "</table>\n</body></html>\n";
  write_file_atomic(out / "report.html", h);
}

}  // namespace ii
