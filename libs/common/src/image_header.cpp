#include "vloc/common/image_header.h"

#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "vloc/common/options.h"

namespace vloc {

namespace {

// Random access to the bytes of an encoded image, in memory or in a file.
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  // False when [offset, offset + n) is not all inside the image.
  virtual bool Read(uint64_t offset, size_t n, uint8_t* out) = 0;
  // The bytes themselves when in memory (scan counting walks them), else null.
  virtual const uint8_t* memory() const { return nullptr; }
  virtual uint64_t size() const = 0;
};

class MemorySource : public ByteSource {
 public:
  MemorySource(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  bool Read(uint64_t offset, size_t n, uint8_t* out) override {
    if (offset > size_ || n > size_ - offset) return false;
    std::copy(data_ + offset, data_ + offset + n, out);
    return true;
  }
  const uint8_t* memory() const override { return data_; }
  uint64_t size() const override { return size_; }

 private:
  const uint8_t* data_;
  size_t size_;
};

class FileSource : public ByteSource {
 public:
  FileSource(std::ifstream& in, uint64_t size) : in_(in), size_(size) {}
  bool Read(uint64_t offset, size_t n, uint8_t* out) override {
    if (offset > size_ || n > size_ - offset) return false;
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n));
    return static_cast<size_t>(in_.gcount()) == n;
  }
  uint64_t size() const override { return size_; }

 private:
  std::ifstream& in_;
  uint64_t size_;
};

uint32_t BigEndian(const uint8_t* p, int n) {
  uint32_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | p[i];
  return v;
}

// PNG: the 8-byte signature, then the IHDR chunk (length 13).
bool ReadPng(ByteSource& src, ImageHeader* h, std::string* error) {
  uint8_t b[29];
  if (!src.Read(0, sizeof(b), b)) return Fail(error, "PNG cut short before the end of its IHDR header");
  if (BigEndian(b + 8, 4) != 13 || std::string(reinterpret_cast<const char*>(b + 12), 4) != "IHDR")
    return Fail(error, "PNG without an IHDR chunk first");
  const uint32_t w = BigEndian(b + 16, 4), ht = BigEndian(b + 20, 4);
  const int depth = b[24], color = b[25];
  if (w == 0 || ht == 0 || w > 0x7fffffffu || ht > 0x7fffffffu)
    return Fail(error, "PNG IHDR size " + std::to_string(w) + " x " + std::to_string(ht) + " is not in [1, 2^31 - 1]");
  int channels = 0;
  bool depth_ok = false;
  switch (color) {
    case 0: channels = 1, depth_ok = depth == 1 || depth == 2 || depth == 4 || depth == 8 || depth == 16; break;
    case 2: channels = 3, depth_ok = depth == 8 || depth == 16; break;
    case 3: channels = 3, depth_ok = depth == 1 || depth == 2 || depth == 4 || depth == 8; break;
    case 4: channels = 2, depth_ok = depth == 8 || depth == 16; break;
    case 6: channels = 4, depth_ok = depth == 8 || depth == 16; break;
    default: return Fail(error, "PNG IHDR colour type " + std::to_string(color) + " is not a PNG colour type");
  }
  if (!depth_ok)
    return Fail(error, "PNG IHDR bit depth " + std::to_string(depth) + " is invalid for colour type " +
                           std::to_string(color));
  if (b[26] != 0 || b[27] != 0 || b[28] > 1) return Fail(error, "PNG IHDR compression, filter or interlace invalid");
  h->format = ImageFormat::kPng;
  h->width = static_cast<int>(w);
  h->height = static_cast<int>(ht);
  h->channels = channels;
  h->bit_depth = depth;
  return true;
}

bool IsSof(uint8_t marker) {
  return marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
}

// Skips entropy-coded data from `pos` to the next marker (0xFF followed by
// neither a stuffed 0x00 nor a restart marker): returns its offset, or size
// when there is none.
uint64_t SkipEntropyData(const uint8_t* data, uint64_t size, uint64_t pos) {
  while (pos + 1 < size) {
    if (data[pos] != 0xFF) {
      ++pos;
      continue;
    }
    const uint8_t next = data[pos + 1];
    if (next == 0x00 || (next >= 0xD0 && next <= 0xD7) || next == 0xFF) {
      pos += next == 0xFF ? 1 : 2;
      continue;
    }
    return pos;
  }
  return size;
}

// JPEG: SOI, then marker segments up to the frame header (SOFn); with
// count_scans, on to EOI, counting the scans (SOS).
bool ReadJpeg(ByteSource& src, bool count_scans, ImageHeader* h, std::string* error) {
  const uint8_t* memory = count_scans ? src.memory() : nullptr;
  uint64_t pos = 2;
  bool have_frame = false;
  for (;;) {
    uint8_t m[2];
    if (!src.Read(pos, 2, m))
      return Fail(error, have_frame ? "JPEG cut short (no end-of-image marker after " + std::to_string(h->jpeg_scans) +
                                          " scan(s))"
                                    : "JPEG cut short before its frame header (SOF)");
    if (m[0] != 0xFF) return Fail(error, "JPEG has no marker at byte " + std::to_string(pos) + ": malformed");
    uint8_t marker = m[1];
    ++pos;
    while (marker == 0xFF) {  // fill bytes
      if (!src.Read(++pos, 1, &marker)) return Fail(error, "JPEG cut short in fill bytes");
    }
    ++pos;  // pos: after the marker
    if (marker == 0xD9) {
      if (!have_frame) return Fail(error, "JPEG ends before its frame header (SOF)");
      return true;
    }
    if ((marker >= 0xD0 && marker <= 0xD7) || marker == 0x01) continue;  // no length
    if (marker == 0xD8 || marker == 0x00) return Fail(error, "JPEG has a misplaced marker at byte " + std::to_string(pos - 2));
    uint8_t l[2];
    if (!src.Read(pos, 2, l)) return Fail(error, "JPEG cut short in a segment length");
    const uint32_t length = BigEndian(l, 2);
    if (length < 2) return Fail(error, "JPEG segment length " + std::to_string(length) + " < 2: malformed");
    const uint64_t segment_end = pos + length;
    if (IsSof(marker)) {
      if (have_frame) return Fail(error, "JPEG with a second frame header (hierarchical JPEG is not supported)");
      uint8_t f[6];
      if (length < 8 || !src.Read(pos + 2, 6, f)) return Fail(error, "JPEG frame header (SOF) cut short");
      const int precision = f[0], height = static_cast<int>(BigEndian(f + 1, 2)),
                width = static_cast<int>(BigEndian(f + 3, 2)), components = f[5];
      if (height == 0 || width == 0)
        return Fail(error, "JPEG frame header gives " + std::to_string(width) + " x " + std::to_string(height) +
                               " (a height set later by a DNL marker is not supported)");
      if (components < 1 || components > 4 || length != 8u + 3u * components)
        return Fail(error, "JPEG frame header with " + std::to_string(components) + " components: malformed");
      h->format = ImageFormat::kJpeg;
      h->width = width;
      h->height = height;
      h->channels = components;
      h->bit_depth = precision;
      h->progressive = marker == 0xC2 || marker == 0xC6 || marker == 0xCA || marker == 0xCE;
      have_frame = true;
      if (!memory) return true;
    } else if (marker == 0xDA) {
      if (!have_frame) return Fail(error, "JPEG scan before its frame header (SOF)");
      ++h->jpeg_scans;
      if (segment_end > src.size()) return Fail(error, "JPEG scan header cut short");
      pos = SkipEntropyData(memory, src.size(), segment_end);
      continue;
    }
    pos = segment_end;
  }
}

// TIFF: the first image file directory (the image imread reads).
bool ReadTiff(ByteSource& src, ImageHeader* h, std::string* error) {
  uint8_t b[8];
  if (!src.Read(0, 8, b)) return Fail(error, "TIFF cut short in its header");
  const bool little = b[0] == 'I';
  auto u = [&](const uint8_t* p, int n) -> uint32_t {
    uint32_t v = 0;
    for (int i = 0; i < n; ++i) v |= uint32_t(p[little ? i : n - 1 - i]) << (8 * i);
    return v;
  };
  if (u(b + 2, 2) == 43) return Fail(error, "BigTIFF is not supported");
  const uint32_t ifd = u(b + 4, 4);
  uint8_t c[2];
  if (!src.Read(ifd, 2, c)) return Fail(error, "TIFF image directory at byte " + std::to_string(ifd) + " cut short");
  const uint32_t entries = u(c, 2);
  int64_t width = -1, height = -1;
  int channels = 1, depth = 1;
  for (uint32_t i = 0; i < entries; ++i) {
    uint8_t e[12];
    if (!src.Read(ifd + 2 + 12ull * i, 12, e)) return Fail(error, "TIFF image directory cut short");
    const uint32_t tag = u(e, 2), type = u(e + 2, 2), count = u(e + 4, 4);
    if (count < 1 || (type != 3 && type != 4)) continue;
    const int size = type == 3 ? 2 : 4;
    uint32_t value = u(e + 8, size);
    if (uint64_t(count) * size > 4) {  // stored elsewhere: the first value is enough
      uint8_t v[4];
      if (!src.Read(u(e + 8, 4), size, v)) return Fail(error, "TIFF tag " + std::to_string(tag) + " cut short");
      value = u(v, size);
    }
    if (tag == 256) width = value;
    if (tag == 257) height = value;
    if (tag == 258) depth = static_cast<int>(value);
    if (tag == 277) channels = static_cast<int>(value);
  }
  if (width <= 0 || height <= 0 || width > 0x7fffffff || height > 0x7fffffff)
    return Fail(error, "TIFF without a valid ImageWidth / ImageLength");
  h->format = ImageFormat::kTiff;
  h->width = static_cast<int>(width);
  h->height = static_cast<int>(height);
  h->channels = channels;
  h->bit_depth = depth;
  return true;
}

bool ReadHeader(ByteSource& src, bool count_jpeg_scans, ImageHeader* header, std::string* error) {
  *header = ImageHeader();
  uint8_t sig[8];
  const size_t n = static_cast<size_t>(std::min<uint64_t>(8, src.size()));
  if (n < 4 || !src.Read(0, n, sig)) return Fail(error, "not an image: " + std::to_string(src.size()) + " bytes");
  static const uint8_t kPng[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  if (n == 8 && std::equal(sig, sig + 8, kPng)) return ReadPng(src, header, error);
  if (sig[0] == 0xFF && sig[1] == 0xD8 && sig[2] == 0xFF) return ReadJpeg(src, count_jpeg_scans, header, error);
  if ((sig[0] == 'I' && sig[1] == 'I' && sig[2] == 42 && sig[3] == 0) ||
      (sig[0] == 'M' && sig[1] == 'M' && sig[2] == 0 && sig[3] == 42) ||
      (sig[0] == 'I' && sig[1] == 'I' && sig[2] == 43) || (sig[0] == 'M' && sig[1] == 'M' && sig[3] == 43))
    return ReadTiff(src, header, error);
  return Fail(error, "not a PNG, JPEG or TIFF image (unknown signature)");
}

std::string Megapixels(int64_t pixels) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f MP", pixels / 1e6);
  return text;
}

}  // namespace

const char* ToString(ImageFormat format) {
  switch (format) {
    case ImageFormat::kPng: return "PNG";
    case ImageFormat::kJpeg: return "JPEG";
    case ImageFormat::kTiff: return "TIFF";
    case ImageFormat::kUnknown: break;
  }
  return "unknown";
}

std::string ImageHeader::Describe() const {
  std::ostringstream s;
  s << ToString(format) << " " << width << " x " << height << " (" << Megapixels(pixels()) << "), " << channels
    << " channel(s) of " << bit_depth << " bit";
  if (progressive) s << ", progressive";
  if (jpeg_scans > 0) s << ", " << jpeg_scans << " scan(s)";
  return s.str();
}

void ImageLimits::Visit(OptionsReader& r) {
  r.Optional("max_width", &max_width, "px, wider encoded images are refused before decoding", AtLeast(1));
  r.Optional("max_height", &max_height, "px, taller encoded images are refused before decoding", AtLeast(1));
  r.Optional("max_pixels", &max_pixels, "px, width x height above this is refused before decoding",
             InRange(1, double(int64_t(1) << 30)));
  r.Optional("max_jpeg_scans", &max_jpeg_scans, "scans of one JPEG (progressive JPEGs have about 10)", AtLeast(1));
}

bool ImageLimits::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string ImageLimits::Describe() const {
  return std::to_string(max_width) + " x " + std::to_string(max_height) + " px, " + Megapixels(max_pixels);
}

bool ReadImageHeader(const uint8_t* data, size_t size, ImageHeader* header, std::string* error,
                     bool count_jpeg_scans) {
  MemorySource src(data, size);
  return ReadHeader(src, count_jpeg_scans, header, error);
}

bool CheckImageHeader(const ImageHeader& h, const ImageLimits& limits, std::string* error) {
  if (h.width > limits.max_width || h.height > limits.max_height || h.pixels() > limits.max_pixels)
    return Fail(error, h.Describe() + ": over the limit of " + limits.Describe() + "; refused before decoding");
  if (h.jpeg_scans > limits.max_jpeg_scans)
    return Fail(error, h.Describe() + ": more than " + std::to_string(limits.max_jpeg_scans) +
                           " scans; refused before decoding");
  return true;
}

bool InspectImage(const uint8_t* data, size_t size, const ImageLimits& limits, ImageHeader* header,
                  std::string* error) {
  // The size first (a bomb is named by its size even when its body is cut
  // short), then the scans of a JPEG.
  if (!ReadImageHeader(data, size, header, error, /*count_jpeg_scans=*/false) ||
      !CheckImageHeader(*header, limits, error))
    return false;
  if (header->format != ImageFormat::kJpeg) return true;
  return ReadImageHeader(data, size, header, error, /*count_jpeg_scans=*/true) &&
         CheckImageHeader(*header, limits, error);
}

bool ReadImageFileHeader(const std::string& path, ImageHeader* header, std::string* error) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return Fail(error, "cannot read image " + path + " (no such file)");
  if (!S_ISREG(st.st_mode)) return Fail(error, path + ": not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) return Fail(error, path + ": cannot open");
  FileSource src(in, static_cast<uint64_t>(st.st_size));
  std::string why;
  if (!ReadHeader(src, /*count_jpeg_scans=*/false, header, &why)) return Fail(error, path + ": " + why);
  return true;
}

bool ReadCheckedImageFile(const std::string& path, const ImageLimits& limits, std::vector<uint8_t>* bytes,
                          ImageHeader* header, std::string* error) {
  std::string why;
  if (!ReadImageFileHeader(path, header, error)) return false;
  if (!CheckImageHeader(*header, limits, &why)) return Fail(error, path + ": " + why);
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  const std::streamoff size = in ? static_cast<std::streamoff>(in.tellg()) : -1;
  if (size <= 0) return Fail(error, path + ": cannot read");
  bytes->resize(static_cast<size_t>(size));
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(bytes->data()), size)) return Fail(error, path + ": cannot read");
  // Again on the bytes that will be decoded (the file may have changed), with a JPEG's scans counted.
  if (!InspectImage(bytes->data(), bytes->size(), limits, header, &why)) return Fail(error, path + ": " + why);
  return true;
}

}  // namespace vloc
