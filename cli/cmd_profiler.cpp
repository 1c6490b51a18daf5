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

#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <regex>

#include "commands.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/profiler/calibration.hpp"
#include "scanmesh/drivers/profiler/camera_profiler.hpp"
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
      j["edge"] = counts.edge;
      j["trimmed"] = counts.trimmed;
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

// ---- calibrate ----

struct CalibrateArgs {
  std::string images;
  std::string laser_images;
  std::string pattern;
  double square_mm = 0;
  std::string output;
  bool fit_k3 = false;
  ExtractionArgs extraction;
  bool json = false;
};

cv::Size parse_pattern(const std::string& text) {
  static const std::regex re(R"((\d{1,3})[xX](\d{1,3}))");
  std::smatch m;
  if (!std::regex_match(text, m, re))
    throw ConfigError("--pattern '" + text + "': expected COLSxROWS, e.g. 9x6 (inner corners)");
  return {std::stoi(m[1]), std::stoi(m[2])};
}

/// Every image of a folder as one 8-bit channel, named by file; an image that does not decode
/// is kept empty (the calibration reports it), others are read with `channel`.
std::vector<prof::NamedImage> load_images(const prof::Media& media,
                                          const std::vector<fs::path>& files,
                                          prof::FrameChannel channel,
                                          std::vector<std::pair<std::string, std::string>>& unreadable) {
  std::vector<prof::NamedImage> out;
  for (const auto& f : files) {
    prof::NamedImage img;
    img.name = f.filename().string();
    try {
      prof::single_channel(media.read_image(f), channel, img.gray);
    } catch (const InputError& e) {
      unreadable.emplace_back(img.name, e.what());
      continue;
    }
    out.push_back(std::move(img));
  }
  return out;
}

json uses_json(const std::vector<prof::ImageUse>& uses,
               const std::vector<std::pair<std::string, std::string>>& unreadable) {
  json arr = json::array();
  for (const auto& u : uses) {
    if (u.used) continue;
    arr.push_back({{"image", u.image}, {"reason", u.reason}});
  }
  for (const auto& [name, why] : unreadable) arr.push_back({{"image", name}, {"reason", why}});
  return arr;
}

/// The calibration report: one JSON form, used by --json and turned into text otherwise.
json calibration_report(const CalibrateArgs& args, const prof::CameraCalibrationResult& cam,
                        const prof::LaserPlaneResult& plane, std::size_t images,
                        std::size_t laser_images,
                        const std::vector<std::pair<std::string, std::string>>& bad_images,
                        const std::vector<std::pair<std::string, std::string>>& bad_lasers,
                        double seconds) {
  json j;
  j["output"] = args.output;
  j["image_width"] = cam.camera.size.width;
  j["image_height"] = cam.camera.size.height;
  j["images"] = images;
  j["images_used"] = cam.poses.size();
  j["rejected_images"] = uses_json(cam.images, bad_images);
  j["reprojection_error_px"] = cam.rms_px;
  json per = json::object();
  for (const auto& u : cam.images)
    if (u.used) per[u.image] = u.error_px;
  j["image_errors_px"] = per;
  const cv::Matx33d& k = cam.camera.matrix;
  j["camera_matrix"] = {{k(0, 0), k(0, 1), k(0, 2)}, {k(1, 0), k(1, 1), k(1, 2)},
                        {k(2, 0), k(2, 1), k(2, 2)}};
  j["distortion_coefficients"] = cam.camera.distortion;
  j["laser_images"] = laser_images;
  std::size_t used = 0;
  json points = json::object();
  for (const auto& u : plane.images)
    if (u.used) {
      ++used;
      points[u.image] = u.points;
    }
  j["laser_images_used"] = used;
  j["rejected_laser_images"] = uses_json(plane.images, bad_lasers);
  j["laser_image_points"] = points;
  j["laser_points"] = plane.points;
  j["laser_inliers"] = plane.inliers;
  j["laser_plane"] = {{"normal", {plane.plane.normal[0], plane.plane.normal[1], plane.plane.normal[2]}},
                      {"distance_mm", plane.plane.distance_mm}};
  j["laser_plane_rms_mm"] = plane.rms_mm;
  j["laser_plane_max_mm"] = plane.max_mm;
  j["seconds"] = seconds;
  return j;
}

void print_report(const json& j) {
  std::printf("camera           %dx%d, %zu of %zu images used, reprojection error %.3f px\n",
              j["image_width"].get<int>(), j["image_height"].get<int>(),
              j["images_used"].get<std::size_t>(), j["images"].get<std::size_t>(),
              j["reprojection_error_px"].get<double>());
  const auto& k = j["camera_matrix"];
  std::printf("  fx %.3f  fy %.3f  cx %.3f  cy %.3f\n", k[0][0].get<double>(),
              k[1][1].get<double>(), k[0][2].get<double>(), k[1][2].get<double>());
  std::printf("  distortion      ");
  for (const auto& d : j["distortion_coefficients"]) std::printf(" %.6g", d.get<double>());
  std::printf("\n");
  for (const auto& r : j["rejected_images"])
    std::printf("  rejected %s: %s\n", r["image"].get<std::string>().c_str(),
                r["reason"].get<std::string>().c_str());
  const auto& n = j["laser_plane"]["normal"];
  std::printf("laser plane      %zu of %zu images used, %zu points, %zu inliers, rms %.4f mm, "
              "max %.4f mm\n",
              j["laser_images_used"].get<std::size_t>(), j["laser_images"].get<std::size_t>(),
              j["laser_points"].get<std::size_t>(), j["laser_inliers"].get<std::size_t>(),
              j["laser_plane_rms_mm"].get<double>(), j["laser_plane_max_mm"].get<double>());
  std::printf("  normal %.6f %.6f %.6f  distance %.4f mm\n", n[0].get<double>(),
              n[1].get<double>(), n[2].get<double>(),
              j["laser_plane"]["distance_mm"].get<double>());
  for (const auto& r : j["rejected_laser_images"])
    std::printf("  rejected %s: %s\n", r["image"].get<std::string>().c_str(),
                r["reason"].get<std::string>().c_str());
  std::printf("written          %s\n", j["output"].get<std::string>().c_str());
}

int run_calibrate(const CalibrateArgs& args) {
  const auto t0 = std::chrono::steady_clock::now();
  prof::ChessboardSpec board{parse_pattern(args.pattern), args.square_mm};
  board.validate();
  const prof::ExtractionOptions extraction = extraction_options(args.extraction);
  const auto board_files = prof::list_images(args.images);
  const auto laser_files = prof::list_images(args.laser_images);
  const prof::Media media = prof::Media::load();
  std::vector<std::pair<std::string, std::string>> bad_images, bad_lasers;
  const auto boards = load_images(media, board_files, prof::FrameChannel::kGray, bad_images);
  // Laser images; NAME_off.EXT is the laser-off image of NAME.EXT.
  std::map<std::string, fs::path> off;
  std::vector<fs::path> on;
  for (const auto& f : laser_files) {
    const std::string stem = f.stem().string();
    if (stem.size() > 4 && stem.compare(stem.size() - 4, 4, "_off") == 0) {
      off[stem.substr(0, stem.size() - 4)] = f;
    } else {
      on.push_back(f);
    }
  }
  auto lasers = load_images(media, on, args.extraction.channel, bad_lasers);
  for (auto& img : lasers) {
    const auto it = off.find(fs::path(img.name).stem().string());
    if (it == off.end()) continue;
    try {
      prof::single_channel(media.read_image(it->second), args.extraction.channel, img.background);
    } catch (const InputError& e) {
      bad_lasers.emplace_back(it->second.filename().string(), e.what());
    }
  }
  prof::CameraCalibrationOptions copts;
  copts.fit_k3 = args.fit_k3;
  const auto cam = prof::calibrate_camera(boards, board, args.images, copts);
  const auto plane = prof::calibrate_laser_plane(lasers, cam, board, extraction, args.laser_images);
  prof::ProfilerCalibration cal;
  cal.camera = cam.camera;
  cal.plane = plane.plane;
  cal.reprojection_error_px = cam.rms_px;
  cal.plane_rms_mm = plane.rms_mm;
  prof::save_calibration(args.output, cal);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const json report = calibration_report(args, cam, plane, board_files.size(), on.size(),
                                         bad_images, bad_lasers, seconds);
  if (args.json) {
    std::cout << report.dump() << "\n";
  } else {
    print_report(report);
  }
  return kExitOk;
}

// ---- read ----

struct ReadArgs {
  std::string source;
  std::string calib;
  std::uint64_t frames = 0;
  std::string name = "profiler";
  int laser_off_every = 0;
  std::optional<double> exposure_us;
  std::optional<double> gain;
  int timeout_ms = 1000;
  double min_z_mm = 0;
  double max_z_mm = 1e9;
  ExtractionArgs extraction;
  bool json = false;
};

/// A profile's one JSON form (`profiler read --json`).
json profile_json(const drivers::Profile& p) {
  json j = {{"seq", p.seq}, {"t_host_ns", p.t_host.ns}};
  if (p.t_device) j["t_device_ns"] = p.t_device->ns;
  j["exposure_us"] = p.exposure_us ? json(*p.exposure_us) : json(nullptr);
  if (p.gain) j["gain"] = *p.gain;
  j["valid"] = p.valid_count();
  json pts = json::array();
  const auto mm = [](double v) { return std::round(v * 1e4) / 1e4; };
  for (const auto& pt : p.points) {
    if (pt.valid()) {
      pts.push_back({mm(pt.x_mm), mm(pt.y_mm), mm(pt.z_mm)});
    } else {
      pts.push_back(nullptr);
    }
  }
  j["points"] = std::move(pts);
  return j;
}

int run_read(const ReadArgs& args) {
  if (args.timeout_ms < 1 || args.timeout_ms > 60000)
    throw ConfigError("profiler read: --timeout must be 1..60000 ms");
  prof::ProfilerConfig config;
  config.calibration = prof::load_calibration(args.calib);
  config.options.name = args.name;
  config.options.timeout = std::chrono::milliseconds(args.timeout_ms);
  config.source = args.source;
  config.settings.exposure_us = args.exposure_us;
  config.settings.gain = args.gain;
  config.extraction = extraction_options(args.extraction);
  config.channel = args.extraction.channel;
  config.laser_off_every = args.laser_off_every;
  config.min_z_mm = args.min_z_mm;
  config.max_z_mm = args.max_z_mm;
  const prof::Media media = prof::Media::load();
  prof::CameraProfiler profiler(config, prof::CameraProfiler::media_factory(media, config));
  profiler.open();  // DeviceError (exit 5): no camera, no files, another frame size
  const auto caps = profiler.capabilities();
  if (args.exposure_us && !caps.exposure_control)
    std::fprintf(stderr, "scanmesh: warning: %s: the source did not accept --exposure-us\n",
                 args.name.c_str());
  if (args.gain && !caps.gain_control)
    std::fprintf(stderr, "scanmesh: warning: %s: the source did not accept --gain\n",
                 args.name.c_str());

  std::mutex mutex;
  std::condition_variable cv;
  std::deque<json> queue;
  std::string lost;
  drivers::ProfilerCallbacks callbacks;
  callbacks.on_profile = [&](const drivers::Profile& p) {
    json j = profile_json(p);  // copied out of the worker's buffer
    std::lock_guard lock(mutex);
    queue.push_back(std::move(j));
    cv.notify_one();
  };
  callbacks.on_state = [&](drivers::DeviceState st, const std::string& reason) {
    if (st != drivers::DeviceState::kLost) return;
    std::lock_guard lock(mutex);
    lost = reason;
    cv.notify_one();
  };
  profiler.start(callbacks);
  const auto quiet_limit = std::max(std::chrono::milliseconds(3000), config.options.timeout * 6);
  std::uint64_t printed = 0;
  std::string failure;
  while (printed < args.frames) {
    std::unique_lock lock(mutex);
    if (!cv.wait_for(lock, quiet_limit, [&] { return !queue.empty() || !lost.empty(); })) {
      failure = args.name + ": no profile for " + std::to_string(quiet_limit.count()) + " ms";
      break;
    }
    if (queue.empty()) {
      failure = lost;
      break;
    }
    json j = std::move(queue.front());
    queue.pop_front();
    lock.unlock();
    if (args.json) {
      std::cout << j.dump() << "\n";
    } else {
      std::cout << j["seq"].get<std::uint64_t>() << "  " << j["t_host_ns"].get<std::int64_t>()
                << "  " << j["valid"].get<std::size_t>() << " of " << j["points"].size()
                << " points\n";
    }
    ++printed;
  }
  profiler.stop();
  std::cout.flush();
  if (printed < args.frames) {
    std::cerr << "scanmesh: " << failure << " (" << printed << " of " << args.frames
              << " profiles)\n";
    return kExitDevice;
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

  auto cal = std::make_shared<CalibrateArgs>();
  CLI::App* ca = cmd->add_subcommand(
      "calibrate", "calibrate the camera from chessboard images and the laser plane from the "
                   "line on the board");
  ca->add_option("--images", cal->images, "folder of chessboard images (the camera's views)")
      ->required();
  ca->add_option("--pattern", cal->pattern,
                 "the board's inner corners (where four squares meet), COLSxROWS, e.g. 9x6")
      ->required();
  ca->add_option("--square", cal->square_mm, "edge of one square, mm")
      ->required()
      ->check(kPositive);
  ca->add_option("--laser-images", cal->laser_images,
                 "folder of images of the laser line on the board at two or more poses; the "
                 "board's pose comes from the --images image of the same name, or from NAME_off "
                 "(the same pose, laser off, subtracted first), or from the image itself")
      ->required();
  ca->add_option("-o,--output", cal->output, "calibration file to write (OpenCV YAML)")
      ->required()
      ->check(output_extension(
          [](const fs::path& p) {
            std::string e = p.extension().string();
            for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
            return e == ".yml" || e == ".yaml";
          },
          ".yml or .yaml"));
  ca->add_flag("--fit-k3", cal->fit_k3, "fit the third radial coefficient too (wide lenses)");
  add_extraction_options(*ca, cal->extraction);
  ca->add_flag("--json", cal->json, "print the calibration report as one JSON object");
  ca->callback([&run, cal] { run = [cal] { return run_calibrate(*cal); }; });

  auto rd = std::make_shared<ReadArgs>();
  CLI::App* re = cmd->add_subcommand("read", "read profiles from a camera or from files");
  re->add_option("--source", rd->source,
                 "a camera (index 0, or /dev/video0), a video file, an image sequence "
                 "(frames/%04d.png) or a folder of images")
      ->required();
  re->add_option("--calib", rd->calib, "calibration file (from profiler calibrate)")->required();
  re->add_option("--frames", rd->frames, "number of profiles to print")
      ->required()
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{1} << 40));
  re->add_option("--name", rd->name, "device name in messages (default profiler)");
  re->add_option("--laser-off-every", rd->laser_off_every,
                 "every Nth frame of the source (0, N, 2N ...) is a laser-off frame, subtracted "
                 "from the frames after it (default 0: none)")
      ->check(CLI::Range(2, 1000000));
  re->add_option("--exposure-us", rd->exposure_us, "manual exposure, where the camera allows")
      ->check(kPositive);
  re->add_option("--gain", rd->gain, "gain (camera units), where the camera allows")
      ->check(kNonNegative);
  re->add_option("--timeout", rd->timeout_ms, "longest wait for one frame, ms (default 1000)");
  re->add_option("--min-z", rd->min_z_mm, "nearest depth measured, mm (default 0)")
      ->check(kNonNegative);
  re->add_option("--max-z", rd->max_z_mm, "farthest depth measured, mm (default none)")
      ->check(kPositive);
  add_extraction_options(*re, rd->extraction);
  re->add_flag("--json", rd->json,
               "one JSON object per profile: seq, t_host_ns, exposure_us, points ([x, y, z] mm "
               "in the camera frame, or null per column)");
  re->callback([&run, rd] { run = [rd] { return run_read(*rd); }; });
}

}  // namespace scanmesh::cli
