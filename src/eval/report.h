#pragma once
// What `eval` writes for people: report.html (the summary, the region beside the whole image,
// each view's metrics and contact sheet, the stage times) and the pictures of a contact sheet.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/image.h"

namespace ii {

// Mean absolute error over the channels, INFERNO colours (black = 0, yellow >= a quarter).
Image error_map(const Image& a, const Image& b);
// The image with the mask's outline drawn in red.
Image with_mask_outline(const Image& image, const std::optional<Image>& mask);
// Panels side by side, each scaled down to 480 pixels wide at most, white gaps.
Image contact_sheet(const std::vector<Image>& panels);
// A metric's value as metrics.json holds it. JSON has no infinity: +inf (identical images' PSNR)
// is the string "inf", NaN (a metric undefined for this view) null.
nlohmann::json metric_json(double value);
// A metric's value (a number, "inf" or null in metrics.json) as text: `decimals` places, ∞ or –.
std::string metric_cell(const nlohmann::json& v, int decimals);
// OUT/report.html from the content of metrics.json.
void write_eval_report(const std::filesystem::path& out, const nlohmann::json& metrics);

}  // namespace ii
