// Calibration files: OpenCV YAML through cv::FileStorage, every key checked on reading (see
// calibration.hpp).
// SPDX-License-Identifier: MIT
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iterator>
#include <optional>
#include <system_error>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/profiler/calibration.hpp"

namespace scanmesh::drivers::profiler {

namespace fs = std::filesystem;

namespace {

/// Largest side of a matrix in a calibration file (the distortion has up to 14 coefficients).
constexpr int kMaxMatrixSide = 16;

/// Reads the keys of one file, each error naming the file and the key.
class Reader {
 public:
  Reader(const cv::FileStorage& storage, const std::string& source)
      : fs_(storage), source_(source) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw InputError(source_ + ": key '" + key + "': " + what);
  }

  cv::FileNode node(const std::string& key) const {
    cv::FileNode n = fs_[key];
    if (n.empty() || n.isNone()) fail(key, "missing");
    return n;
  }

  int integer(const std::string& key, int lo, int hi) const {
    const cv::FileNode n = node(key);
    if (!n.isInt()) fail(key, "not an integer");
    const int v = static_cast<int>(n);
    if (v < lo || v > hi)
      fail(key, std::to_string(v) + " out of " + std::to_string(lo) + ".." + std::to_string(hi));
    return v;
  }

  double real(const std::string& key) const {
    const cv::FileNode n = node(key);
    if (!n.isReal() && !n.isInt()) fail(key, "not a number");
    const double v = static_cast<double>(n);
    if (!std::isfinite(v)) fail(key, "not finite");
    return v;
  }

  std::optional<double> optional_real(const std::string& key) const {
    const cv::FileNode n = fs_[key];
    if (n.empty() || n.isNone()) return std::nullopt;
    return real(key);
  }

  /// An !!opencv-matrix (any numeric type; one channel) as doubles, all finite.
  cv::Mat matrix(const std::string& key) const {
    const cv::FileNode n = node(key);
    if (!n.isMap()) fail(key, "not an OpenCV matrix (!!opencv-matrix with rows, cols, dt, data)");
    // The shape is checked before OpenCV allocates it (a file may claim any size).
    const cv::FileNode rows = n["rows"], cols = n["cols"], data = n["data"];
    if (!rows.isInt() || !cols.isInt() || !n["dt"].isString() || !data.isSeq())
      fail(key, "not an OpenCV matrix (!!opencv-matrix with rows, cols, dt, data)");
    const int r = static_cast<int>(rows), c = static_cast<int>(cols);
    if (r < 0 || c < 0 || r > kMaxMatrixSide || c > kMaxMatrixSide)
      fail(key, std::to_string(r) + " x " + std::to_string(c) + " is not the size of a " +
                    "calibration matrix");
    const std::string dt = static_cast<std::string>(n["dt"]);
    if (dt.size() != 1 || std::string_view("ucwsifd").find(dt[0]) == std::string_view::npos)
      fail(key, "element type '" + dt + "': one of u c w s i f d");
    if (data.size() != static_cast<std::size_t>(r) * static_cast<std::size_t>(c))
      fail(key, "holds " + std::to_string(data.size()) + " values for " + std::to_string(r) +
                    " x " + std::to_string(c));
    cv::Mat m;
    try {
      n >> m;
    } catch (const cv::Exception& e) {
      fail(key, "not an OpenCV matrix: " + e.err);
    }
    if (m.empty()) {
      if (r * c != 0) fail(key, "not an OpenCV matrix (!!opencv-matrix with rows, cols, dt, data)");
      return cv::Mat(0, 1, CV_64F);
    }
    if (m.channels() != 1) fail(key, "a matrix of " + std::to_string(m.channels()) + " channels");
    cv::Mat d;
    m.convertTo(d, CV_64F);
    for (auto it = d.begin<double>(); it != d.end<double>(); ++it)
      if (!std::isfinite(*it)) fail(key, "holds a value that is not finite");
    return d;
  }

 private:
  const cv::FileStorage& fs_;
  const std::string& source_;
};

std::string now_utc() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace

ProfilerCalibration parse_calibration(std::string_view text, const std::string& source) {
  if (text.empty()) throw InputError(source + ": empty file, not a calibration");
  cv::FileStorage storage;
  try {
    storage.open(std::string(text), cv::FileStorage::READ | cv::FileStorage::MEMORY);
  } catch (const cv::Exception& e) {
    throw InputError(source + ": not a calibration file cv::FileStorage can parse: " + e.err);
  } catch (const std::exception& e) {
    // OpenCV 4.6's parser lets std::length_error out of some malformed input.
    throw InputError(source + ": not a calibration file cv::FileStorage can parse: " + e.what());
  }
  if (!storage.isOpened())
    throw InputError(source + ": not a YAML, JSON or XML file cv::FileStorage can read");
  const Reader r(storage, source);
  ProfilerCalibration cal;
  cal.source = source;
  try {
    cal.camera.size.width = r.integer("image_width", 2, 65535);
    cal.camera.size.height = r.integer("image_height", 2, 65535);
    const cv::Mat k = r.matrix("camera_matrix");
    if (k.rows != 3 || k.cols != 3)
      r.fail("camera_matrix", "must be 3 x 3, is " + std::to_string(k.rows) + " x " +
                                  std::to_string(k.cols));
    cal.camera.matrix = cv::Matx33d(k);
    const cv::Mat d = r.matrix("distortion_coefficients");
    if (d.rows > 1 && d.cols > 1)
      r.fail("distortion_coefficients", "must be a row or a column of coefficients");
    cal.camera.distortion.assign(d.begin<double>(), d.end<double>());
    auto problems = camera_problems(cal.camera);
    if (!problems.empty()) r.fail("camera_matrix/distortion_coefficients", problems.front());

    const cv::Mat n = r.matrix("laser_plane_normal");
    if (n.total() != 3) r.fail("laser_plane_normal", "must hold 3 values");
    cv::Vec3d normal(n.at<double>(0), n.at<double>(1), n.at<double>(2));
    double distance = r.real("laser_plane_distance_mm");
    const double norm = cv::norm(normal);
    if (!(norm > 1e-9) || !std::isfinite(norm)) r.fail("laser_plane_normal", "is zero");
    normal *= 1.0 / norm;
    distance /= norm;
    if (distance < 0) {
      normal = -normal;
      distance = -distance;
    }
    if (!(distance > 0))
      r.fail("laser_plane_distance_mm", "0: the plane passes through the camera's centre");
    cal.plane = LaserPlane{normal, distance};
    if (auto v = r.optional_real("reprojection_error_px")) cal.reprojection_error_px = *v;
    if (auto v = r.optional_real("laser_plane_rms_mm")) cal.plane_rms_mm = *v;
  } catch (const InputError&) {
    throw;
  } catch (const cv::Exception& e) {
    throw InputError(source + ": cannot read the calibration: " + e.err);
  } catch (const std::exception& e) {
    throw InputError(source + ": cannot read the calibration: " + e.what());
  }
  return cal;
}

ProfilerCalibration load_calibration(const fs::path& file) {
  std::error_code ec;
  if (fs::is_directory(file, ec)) throw InputError(file.string() + ": cannot read: is a folder");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string() + ": cannot read: " + std::strerror(errno));
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) throw InputError(file.string() + ": cannot read: " + std::strerror(errno));
  return parse_calibration(text, file.string());
}

void save_calibration(const fs::path& file, const ProfilerCalibration& c) {
  // Written beside the final name, then renamed: a failure leaves nothing under the final name.
  const fs::path tmp = file.string() + ".tmp";
  try {
    cv::FileStorage out(tmp.string(), cv::FileStorage::WRITE | cv::FileStorage::FORMAT_YAML);
    if (!out.isOpened())
      throw OutputError(file.string() + ": cannot write: " + std::strerror(errno));
    out.writeComment("scanmesh line profiler calibration: camera frame as OpenCV's (x right, y "
                     "down, z forward), mm; laser plane: normal . X = distance");
    out << "calibrated_at" << now_utc();
    out << "image_width" << c.camera.size.width;
    out << "image_height" << c.camera.size.height;
    out << "camera_matrix" << cv::Mat(c.camera.matrix);
    out << "distortion_coefficients" << cv::Mat(c.camera.distortion, true).reshape(1, 1);
    out << "laser_plane_normal" << cv::Mat(c.plane.normal);
    out << "laser_plane_distance_mm" << c.plane.distance_mm;
    if (std::isfinite(c.reprojection_error_px))
      out << "reprojection_error_px" << c.reprojection_error_px;
    if (std::isfinite(c.plane_rms_mm)) out << "laser_plane_rms_mm" << c.plane_rms_mm;
    out.release();
  } catch (const cv::Exception& e) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw OutputError(file.string() + ": cannot write: " + e.err);
  }
  std::error_code ec;
  if (fs::file_size(tmp, ec) == 0 || ec) {
    fs::remove(tmp, ec);
    throw OutputError(file.string() + ": cannot write (disk full?)");
  }
  fs::rename(tmp, file, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw OutputError(file.string() + ": cannot write: " + ec.message());
  }
}

}  // namespace scanmesh::drivers::profiler
