#include "vloc/common/pds_product.h"

#include <cmath>
#include <filesystem>
#include <sstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "vloc/common/image_header.h"

namespace vloc {

namespace fs = std::filesystem;

namespace {

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

bool IsBrowseExtension(const fs::path& p) {
  const std::string ext = Upper(p.extension().string());
  return ext == ".JPG" || ext == ".JPEG" || ext == ".PNG";
}

const char* const kBrowseExtensions[] = {".jpg", ".JPG", ".jpeg", ".JPEG", ".png", ".PNG",
                                         ".IMG.png", ".IMG.jpg", ".img.png", ".img.jpg"};

// The detached label beside a browse image, or "": X.LBL for X.jpg and
// X.IMG.png, ...M1.LBL for ...M_.jpg.
std::string FindLabelOfBrowse(const fs::path& image) {
  std::vector<std::string> stems;
  fs::path stem = image.parent_path() / image.stem();
  stems.push_back(stem.string());
  if (Upper(stem.extension().string()) == ".IMG") stems.push_back((stem.parent_path() / stem.stem()).string());
  for (size_t k = 0, n = stems.size(); k < n; ++k)
    if (!stems[k].empty() && stems[k].back() == '_') stems.push_back(stems[k].substr(0, stems[k].size() - 1) + "1");
  for (const std::string& s : stems)
    for (const char* ext : {".LBL", ".lbl"})
      if (fs::is_regular_file(s + ext)) return s + ext;
  return "";
}

// The .IMG a detached label's ^IMAGE names (as written, upper or lower case), or "".
std::string FindImageFile(const fs::path& label, const std::string& name) {
  if (name.empty()) return "";
  std::string lower = name;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const std::string& n : {name, Upper(name), lower})
    if (fs::is_regular_file(label.parent_path() / n)) return (label.parent_path() / n).string();
  return "";
}

// 8-bit grey from what the product holds (PDS: 8 / 16 bit; browse: grey or colour).
cv::Mat ToGrey8(cv::Mat image) {
  if (image.depth() == CV_16U) {
    double max = 0;
    cv::minMaxLoc(image.reshape(1), nullptr, &max);
    image.convertTo(image, CV_8U, max <= 4095 ? 1.0 / 16 : 1.0 / 256);
  }
  if (image.depth() != CV_8U) return cv::Mat();
  if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2GRAY);
  if (image.channels() == 2) cv::extractChannel(image, image, 0);
  return image;
}

bool Fail(std::string* error, const std::string& text) {
  *error = text;
  return false;
}

bool SameCahv(const CahvModel& a, const CahvModel& b) {
  return a.kind == CahvKind::kCahv && b.kind == CahvKind::kCahv && (a.a - b.a).norm() < 1e-9 &&
         (a.h - b.h).norm() < 1e-9 * a.h.norm() && (a.v - b.v).norm() < 1e-9 * a.v.norm();
}

// Largest row difference of points seen by both models: a grid of the left
// model's pixels at range_m.
double MaxRowError(const CahvModel& left, const CahvModel& right, cv::Size size, double range_m) {
  double worst = 0;
  for (int gy = 0; gy <= 16; ++gy)
    for (int gx = 0; gx <= 16; ++gx) {
      const Eigen::Vector2d px((size.width - 1) * gx / 16.0, (size.height - 1) * gy / 16.0);
      const std::optional<CameraRay> ray = left.BackProject(px);
      if (!ray) continue;
      const Eigen::Vector3d p = ray->At(range_m);
      const std::optional<Eigen::Vector2d> l = left.Project(p), r = right.Project(p);
      if (!l || !r || r->x() < 0 || r->y() < 0 || r->x() > size.width - 1 || r->y() > size.height - 1) continue;
      worst = std::max(worst, std::abs(l->y() - r->y()));
    }
  return worst;
}

}  // namespace

std::string FindPdsBrowseImage(const std::string& label_path) {
  const fs::path label(label_path);
  const std::string stem = (label.parent_path() / label.stem()).string();
  std::vector<std::string> bases = {stem};
  if (!label.stem().string().empty()) bases.push_back(stem.substr(0, stem.size() - 1) + "_");  // ...M1.LBL -> ...M_.jpg
  for (const std::string& base : bases)
    for (const char* ext : kBrowseExtensions)
      if (fs::is_regular_file(base + ext)) return base + ext;
  return "";
}

bool IsPdsProductPath(const std::string& path) {
  const std::string ext = Upper(fs::path(path).extension().string());
  if (ext == ".IMG" || ext == ".LBL") return true;
  return IsBrowseExtension(path) && !FindLabelOfBrowse(path).empty();
}

bool ReadPdsProduct(const std::string& path, PdsProduct* out, std::string* error, int max_image_side) {
  *out = PdsProduct();
  const fs::path p(path);
  if (!fs::is_regular_file(p)) return Fail(error, path + ": no such file");
  const std::string ext = Upper(p.extension().string());
  // The label: in the .IMG, beside it, the .LBL itself, or beside the browse image.
  if (ext == ".IMG") {
    out->label_path = path;
    for (const char* lbl : {".LBL", ".lbl"})
      if (fs::is_regular_file(fs::path(p).replace_extension(lbl))) out->label_path = fs::path(p).replace_extension(lbl).string();
  } else if (ext == ".LBL") {
    out->label_path = path;
  } else if (IsBrowseExtension(p)) {
    out->label_path = FindLabelOfBrowse(p);
    if (out->label_path.empty())
      return Fail(error, path + ": no PDS label beside it (X.LBL for X.jpg or X.IMG.png, ...M1.LBL for ...M_.jpg)");
    out->image_path = path;
  } else {
    return Fail(error, path + ": not a PDS product (.IMG, .LBL, or a .jpg / .png browse image with its .LBL)");
  }
  if (!ReadPdsCameraLabel(out->label_path, &out->label, error)) return false;
  const PdsCameraLabel& l = out->label;
  if (l.lines > max_image_side || l.line_samples > max_image_side)
    return Fail(error, out->label_path + ": LINES of IMAGE: " + std::to_string(l.line_samples) + " x " +
                           std::to_string(l.lines) + " is over " + std::to_string(max_image_side) + " px a side");
  // The pixels: the .IMG (read through the label), else the browse image.
  if (out->image_path.empty()) {
    if (out->label_path == path && ext == ".IMG") {
      out->image_path = path;
    } else {
      const std::string img = ext == ".IMG" ? path : FindImageFile(out->label_path, l.image_file);
      out->image_path = img.empty() ? FindPdsBrowseImage(out->label_path) : img;
      if (out->image_path.empty())
        return Fail(error, out->label_path + ": ^IMAGE: its file " + (l.image_file.empty() ? "(none named)" : l.image_file) +
                               " is absent and no browse image (.jpg, .png) lies beside the label");
    }
  }
  cv::Mat image;
  if (Upper(fs::path(out->image_path).extension().string()) == ".IMG") {
    // A detached label's .IMG holds no label: its pixels are read through the label file.
    if (!ReadPdsImage(out->label_path, &image, error)) return false;
  } else {
    std::vector<uint8_t> bytes;
    ImageHeader header;
    ImageLimits limits;
    limits.max_width = limits.max_height = max_image_side;
    if (!ReadCheckedImageFile(out->image_path, limits, &bytes, &header, error)) return false;
    if (l.lines > 0 && (header.width != l.line_samples || header.height != l.lines))
      return Fail(error, out->label_path + ": LINES / LINE_SAMPLES of IMAGE: the label says " +
                             std::to_string(l.line_samples) + " x " + std::to_string(l.lines) + ", its browse image " +
                             out->image_path + " is " + std::to_string(header.width) + " x " +
                             std::to_string(header.height) + " (a thumbnail? the camera model is for the full frame)");
    image = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
    if (image.empty()) return Fail(error, out->image_path + ": " + header.Describe() + " cannot be decoded (corrupt?)");
  }
  out->image = ToGrey8(image);
  if (out->image.empty()) return Fail(error, out->image_path + ": SAMPLE_BITS: not an 8- or 16-bit image");
  return true;
}

bool RectifyPdsPair(const CahvModel& left_model, const CahvModel& right_model, const cv::Mat& left,
                    const cv::Mat& right, double range_m, RectifiedPdsPair* out, std::string* error) {
  *out = RectifiedPdsPair();
  if (left.empty() || left.size() != right.size())
    return Fail(error, "the two images differ in size: " + std::to_string(left.cols) + " x " + std::to_string(left.rows) +
                           " and " + std::to_string(right.cols) + " x " + std::to_string(right.rows));
  const cv::Size size = left.size();
  out->raw_kind[0] = left_model.kind, out->raw_kind[1] = right_model.kind;
  out->max_raw_row_error_px = MaxRowError(left_model, right_model, size, range_m);
  if (SameCahv(left_model, right_model)) {
    out->models = {left_model, right_model, size};
    out->left = left, out->right = right;
    out->max_model_row_error_px = out->max_raw_row_error_px;
    return true;
  }
  try {
    out->models = LineariseStereoPair(left_model, right_model, size);
  } catch (const std::invalid_argument& e) {
    return Fail(error, std::string("the camera models cannot be rectified as a stereo pair: ") + e.what());
  }
  out->linearised = true;
  out->max_model_row_error_px = MaxRowError(out->models.left, out->models.right, size, range_m);
  const CahvModel* raw[2] = {&left_model, &right_model};
  const CahvModel* rect[2] = {&out->models.left, &out->models.right};
  const cv::Mat* in[2] = {&left, &right};
  cv::Mat* rectified[2] = {&out->left, &out->right};
  for (int k = 0; k < 2; ++k) {
    cv::Mat map_x, map_y;
    RectificationMaps(*raw[k], *rect[k], size, range_m, &map_x, &map_y);
    cv::remap(*in[k], *rectified[k], map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  }
  return true;
}

bool ReadPdsStereoPair(const std::string& left_path, const std::string& right_path, bool rectify, double range_m,
                       RectifiedPdsPair* out, std::string* error) {
  PdsProduct products[2];
  for (int k = 0; k < 2; ++k)
    if (!ReadPdsProduct(k ? right_path : left_path, &products[k], error)) return false;
  if (!rectify) {
    *out = RectifiedPdsPair();
    out->models = {products[0].label.camera, products[1].label.camera, products[0].image.size()};
    out->raw_kind[0] = products[0].label.camera.kind, out->raw_kind[1] = products[1].label.camera.kind;
    out->left = products[0].image, out->right = products[1].image;
    return true;
  }
  if (products[0].image.size() != products[1].image.size())
    return Fail(error, products[1].label_path + ": LINES / LINE_SAMPLES of IMAGE: " +
                           std::to_string(products[1].image.cols) + " x " + std::to_string(products[1].image.rows) +
                           ", the left product " + products[0].label_path + " is " +
                           std::to_string(products[0].image.cols) + " x " + std::to_string(products[0].image.rows));
  if (!RectifyPdsPair(products[0].label.camera, products[1].label.camera, products[0].image, products[1].image, range_m,
                      out, error)) {
    *error = products[0].label_path + " + " + products[1].label_path + ": GEOMETRIC_CAMERA_MODEL_PARMS: " + *error;
    return false;
  }
  return true;
}

std::string DescribeRectification(const RectifiedPdsPair& pair) {
  std::ostringstream os;
  os << "rectification: {linearised: " << (pair.linearised ? "true" : "false")
     << ", raw_row_error_max_px: " << pair.max_raw_row_error_px
     << ", model_row_error_max_px: " << pair.max_model_row_error_px << ", raw_models: [" << CahvKindName(pair.raw_kind[0])
     << ", " << CahvKindName(pair.raw_kind[1]) << "]}  # row errors: points both models see, from the models\n";
  return os.str();
}

bool WriteRectifiedPair(const RectifiedPdsPair& pair, const std::string& prefix, std::string* error) {
  if (cv::imwrite(prefix + "_left.png", pair.left) && cv::imwrite(prefix + "_right.png", pair.right)) return true;
  return Fail(error, "cannot write " + prefix + "_left.png / _right.png (check the folder)");
}

}  // namespace vloc
