// `scanmesh profiler extract|calibrate|read`: the camera + line-laser profiler from the command
// line (drivers/profiler/README.md).
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.hpp"
#include "scanmesh/drivers/profiler/extraction.hpp"
#include "scanmesh/drivers/profiler/media.hpp"

namespace scanmesh::cli {

namespace {

using nlohmann::json;
namespace prof = scanmesh::drivers::profiler;
namespace fs = std::filesystem;

const std::map<std::string, prof::PeakMethod> kMethods{
    {"cog", prof::PeakMethod::kCentreOfGravity}, {"gaussian", prof::PeakMethod::kGaussian}};
const std::map<std::string, prof::FrameChannel> kChannels{{"red", prof::FrameChannel::kRed},
                                                          {"green", prof::FrameChannel::kGreen},
                                                          {"blue", prof::FrameChannel::kBlue},
                                                          {"gray", prof::FrameChannel::kGray}};

/// The extraction flags `extract`, `calibrate` and `read` share.
struct ExtractionArgs {
  prof::ExtractionOptions options;
  prof::FrameChannel channel = prof::FrameChannel::kRed;
  bool rows = false;
};

void add_extraction_options(CLI::App& cmd, ExtractionArgs& a) {
  cmd.add_flag("--rows", a.rows,
               "the line runs down the image: one position (a column) per row instead of one "
               "row per column");
  cmd.add_option("--method", a.options.method, "sub-pixel centre: cog (default) or gaussian")
      ->transform(CLI::CheckedTransformer(kMethods, CLI::ignore_case));
  cmd.add_option("--channel", a.channel,
                 "channel of colour images carrying the laser: red (default), green, blue, gray")
      ->transform(CLI::CheckedTransformer(kChannels, CLI::ignore_case));
  cmd.add_option("--min-contrast", a.options.min_contrast,
                 "least level of a peak above its column (default 24)")
      ->check(CLI::Range(1, 255));
  cmd.add_option("--max-width", a.options.max_width_px,
                 "widest line in pixels; wider is a blob (default 16)")
      ->check(CLI::Range(2, 255));
  cmd.add_option("--trim-ends", a.options.trim_ends,
                 "values dropped at each end of a run of columns before a gap, where the line "
                 "falls off an edge (default 2)")
      ->check(CLI::Range(0, 16));
}

prof::ExtractionOptions extraction_options(const ExtractionArgs& a) {
  prof::ExtractionOptions o = a.options;
  o.axis = a.rows ? prof::LineAxis::kRows : prof::LineAxis::kColumns;
  o.validate();
  return o;
}

json positions_json(const std::vector<float>& positions) {
  json arr = json::array();
  for (float p : positions) {
    if (std::isfinite(p)) {
      arr.push_back(std::round(static_cast<double>(p) * 1e4) / 1e4);
    } else {
      arr.push_back(nullptr);
    }
  }
  return arr;
}

struct ExtractArgs {
  std::string images;
  std::string background;
  ExtractionArgs extraction;
  bool json = false;
};

int run_extract(const ExtractArgs& args) {
  const auto files = prof::list_images(args.images);
  const prof::Media media = prof::Media::load();
  prof::LineExtractor extractor(extraction_options(args.extraction));
  cv::Mat background;
  if (!args.background.empty())
    prof::single_channel(media.read_image(args.background), args.extraction.channel, background);
  std::vector<float> positions;
  cv::Mat gray;
  for (const auto& file : files) {
    prof::single_channel(media.read_image(file), args.extraction.channel, gray);
    if (!background.empty() && background.size() != gray.size())
      throw InputError(file.string() + ": " + std::to_string(gray.cols) + "x" +
                       std::to_string(gray.rows) + ", but the background " + args.background +
                       " is " + std::to_string(background.cols) + "x" +
                       std::to_string(background.rows));
    const prof::ExtractionCounts counts = extractor.extract(gray, background, positions);
    const std::string name = file.filename().string();
    if (args.json) {
      json j = {{"image", name}, {"positions", positions_json(positions)}};
      j["found"] = counts.found;
      j["weak"] = counts.weak;
      j["too_wide"] = counts.too_wide;
      j["saturated"] = counts.saturated;
      j["ambiguous"] = counts.ambiguous;
      std::cout << j.dump() << "\n";
      continue;
    }
    std::cout << name << "  " << counts.found << " of " << positions.size()
              << (args.extraction.rows ? " rows" : " columns") << "\n ";
    for (float p : positions) {
      if (std::isfinite(p)) {
        char buf[32];
        std::snprintf(buf, sizeof buf, " %.3f", static_cast<double>(p));
        std::cout << buf;
      } else {
        std::cout << " -";
      }
    }
    std::cout << "\n";
  }
  return kExitOk;
}

}  // namespace

void add_profiler_command(CLI::App& app, Runner& run) {
  CLI::App* cmd = app.add_subcommand(
      "profiler", "camera + line-laser profiler: extract the line, calibrate, read profiles");
  cmd->require_subcommand(1);

  auto extract = std::make_shared<ExtractArgs>();
  CLI::App* ex = cmd->add_subcommand(
      "extract", "print the sub-pixel line position per column (or row) of every image");
  ex->add_option("--images", extract->images, "folder of images, read in name order")->required();
  ex->add_option("--background", extract->background,
                 "a laser-off image subtracted from every image first");
  add_extraction_options(*ex, extract->extraction);
  ex->add_flag("--json", extract->json,
               "one JSON object per image: {\"image\": NAME, \"positions\": [row or null ...]}");
  ex->callback([&run, extract] { run = [extract] { return run_extract(*extract); }; });
}

}  // namespace scanmesh::cli
