#pragma once
// An encoded image's size from its header, without decoding it: PNG (IHDR),
// JPEG (SOF0..SOF15, baseline, progressive, lossless, arithmetic) and TIFF
// (the first IFD, as OpenCV's imread reads it). Anything else is refused.
// Encoded images are decompression bombs until proven otherwise: a 1 MB PNG
// can claim 32,000 x 32,000 pixels, and a decoder allocates what the header
// says. Check the header against ImageLimits before handing bytes to
// cv::imdecode / cv::imread:
//
//   ImageHeader header;
//   std::string why;
//   if (!InspectImage(bytes.data(), bytes.size(), limits, &header, &why))
//     throw std::invalid_argument("image 'navcam_left': " + why);  // e.g. "PNG 12000 x 12000 ... over the limit ..."
//   cv::Mat image = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);   // now bounded by the limits
//
// A file: ReadCheckedImageFile(path, limits, &bytes, &header, &why), then
// cv::imdecode(bytes, ...).
//
// For a JPEG in memory the scans are counted too (every progressive scan
// makes the decoder pass over the whole image again).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace vloc {

class OptionsReader;

enum class ImageFormat { kUnknown, kPng, kJpeg, kTiff };
const char* ToString(ImageFormat format);  // "PNG", "JPEG", "TIFF", "unknown"

struct ImageHeader {
  ImageFormat format = ImageFormat::kUnknown;
  int width = 0;            // px
  int height = 0;           // px
  int channels = 0;         // samples per pixel as stored (PNG palette: 3)
  int bit_depth = 0;        // bits per sample
  bool progressive = false;  // JPEG progressive (SOF2, SOF6, SOF10, SOF14)
  int jpeg_scans = 0;       // JPEG in memory: scans (SOS markers); 0 = not counted

  int64_t pixels() const { return int64_t(width) * height; }
  // "PNG 12000 x 12000, 1 channel(s) of 16 bit" (+ ", progressive, 12 scans" for a JPEG).
  std::string Describe() const;
};

// The largest image a reader accepts. Defaults fit any drone photo (about
// 100 MP); a channel with a known camera sets its own (a Navcam image is
// 1024 x 1024).
struct ImageLimits {
  int max_width = 20000;            // px
  int max_height = 20000;           // px
  int64_t max_pixels = 100000000;   // px, width x height
  int max_jpeg_scans = 100;         // scans of one JPEG (a progressive JPEG has about 10)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
  // "4096 x 4096 px, 16.8 MP".
  std::string Describe() const;
};

// Reads the header of `size` bytes of an encoded image. False with one line
// in *error when the bytes are no PNG, JPEG or TIFF, or the header is
// malformed or cut short. Reads headers only: the pixel data need not be
// valid. With count_jpeg_scans, a JPEG's segments are walked to its end and
// its scans counted (and a JPEG without an end marker is refused).
bool ReadImageHeader(const uint8_t* data, size_t size, ImageHeader* header, std::string* error,
                     bool count_jpeg_scans = true);

// False with one line in *error ("PNG 12000 x 12000, ... over the limit of
// 4096 x 4096 px, 16.8 MP") when the header exceeds the limits.
bool CheckImageHeader(const ImageHeader& header, const ImageLimits& limits, std::string* error);

// ReadImageHeader + CheckImageHeader.
bool InspectImage(const uint8_t* data, size_t size, const ImageLimits& limits, ImageHeader* header,
                  std::string* error);

// The header of an image file: reads its first 64 kB, more (up to the whole
// file) only when the header lies further in (a JPEG after large EXIF
// segments). JPEG scans are not counted. *error names the file.
bool ReadImageFileHeader(const std::string& path, ImageHeader* header, std::string* error);

// An image file's bytes, read only after its header passed: the header from
// the file (a 32,000 x 32,000 bomb is refused before its bytes are read),
// then the whole file, checked again as InspectImage (JPEG scans counted).
// Decode them with cv::imdecode. False with one line in *error naming the
// file.
bool ReadCheckedImageFile(const std::string& path, const ImageLimits& limits, std::vector<uint8_t>* bytes,
                          ImageHeader* header, std::string* error);

}  // namespace vloc
