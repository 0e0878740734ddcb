#include "vloc/tunnel/frame.h"

#include <algorithm>
#include <cstring>

namespace vloc::tunnel {
namespace {

class Writer {
 public:
  explicit Writer(size_t reserve) { out_.reserve(reserve); }
  template <class T>
  void Put(T v) {
    for (size_t i = 0; i < sizeof(T); ++i) out_.push_back(static_cast<uint8_t>(static_cast<uint64_t>(v) >> (8 * i)));
  }
  void Bytes(const void* p, size_t n) {
    const auto* b = static_cast<const uint8_t*>(p);
    out_.insert(out_.end(), b, b + n);
  }
  std::vector<uint8_t> Take() { return std::move(out_); }

 private:
  std::vector<uint8_t> out_;
};

class Reader {
 public:
  Reader(const uint8_t* p, size_t n) : p_(p), n_(n) {}
  template <class T>
  bool Get(T* v) {
    if (n_ - pos_ < sizeof(T)) return false;
    uint64_t x = 0;
    for (size_t i = 0; i < sizeof(T); ++i) x |= static_cast<uint64_t>(p_[pos_ + i]) << (8 * i);
    *v = static_cast<T>(x);
    pos_ += sizeof(T);
    return true;
  }
  bool String(size_t max, std::string* s) {
    uint8_t len = 0;
    if (!Get(&len) || len > max || n_ - pos_ < len) return false;
    s->assign(reinterpret_cast<const char*>(p_ + pos_), len);
    pos_ += len;
    return true;
  }
  size_t left() const { return n_ - pos_; }
  const uint8_t* here() const { return p_ + pos_; }

 private:
  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
};

void PutHeader(Writer& w, FrameKind kind, uint8_t flags, uint64_t session) {
  w.Put<uint32_t>(kMagic);
  w.Put<uint8_t>(static_cast<uint8_t>(kind));
  w.Put<uint8_t>(flags);
  w.Put<uint16_t>(0);
  w.Put<uint64_t>(session);
}

bool Fail(std::string* error, const char* what) {
  if (error) *error = what;
  return false;
}

}  // namespace

bool ValidChannelName(const std::string& channel) {
  if (channel.empty() || channel.size() > kMaxChannelBytes) return false;
  for (char c : channel)
    if (c < 0x21 || c > 0x7e) return false;
  return true;
}

std::vector<uint8_t> EncodeData(uint64_t session, const DataFrame& d) {
  Writer w(kDataOverheadBytes + d.chunk_size);
  PutHeader(w, FrameKind::kData, 0, session);
  w.Put<uint64_t>(d.seq);
  w.Put<uint64_t>(d.msg_id);
  w.Put<int64_t>(d.send_utime);
  w.Put<uint32_t>(d.total_size);
  w.Put<uint32_t>(d.offset);
  w.Put<uint8_t>(static_cast<uint8_t>(d.channel.size()));
  w.Bytes(d.channel.data(), d.channel.size());
  w.Put<uint32_t>(static_cast<uint32_t>(d.chunk_size));
  if (d.chunk_size) w.Bytes(d.chunk, d.chunk_size);
  return w.Take();
}

std::vector<uint8_t> EncodeControl(uint64_t session, uint8_t flags, const ControlFrame& c) {
  Writer w(kHeaderBytes + 17 + c.name.size());
  PutHeader(w, FrameKind::kControl, flags, session);
  w.Put<uint64_t>(c.acked_session);
  w.Put<uint64_t>(c.acked_seq);
  const size_t n = std::min(c.name.size(), kMaxNameBytes);
  w.Put<uint8_t>(static_cast<uint8_t>(n));
  w.Bytes(c.name.data(), n);
  return w.Take();
}

bool DecodeFrame(const uint8_t* bytes, size_t size, const FrameLimits& limits, Frame* f, std::string* error) {
  Reader r(bytes, size);
  uint32_t magic = 0;
  uint8_t kind = 0;
  uint16_t reserved = 0;
  if (!r.Get(&magic) || !r.Get(&kind) || !r.Get(&f->flags) || !r.Get(&reserved) || !r.Get(&f->session))
    return Fail(error, "frame shorter than its header");
  if (magic != kMagic) return Fail(error, "bad magic (not a vloc tunnel frame)");
  if (f->session == 0) return Fail(error, "session 0");
  if (kind == static_cast<uint8_t>(FrameKind::kControl)) {
    f->kind = FrameKind::kControl;
    if (!r.Get(&f->control.acked_session) || !r.Get(&f->control.acked_seq) ||
        !r.String(kMaxNameBytes, &f->control.name))
      return Fail(error, "truncated control frame");
    if (r.left() != 0) return Fail(error, "control frame longer than its fields");
    return true;
  }
  if (kind != static_cast<uint8_t>(FrameKind::kData)) return Fail(error, "unknown frame kind");
  f->kind = FrameKind::kData;
  DataFrame& d = f->data;
  if (!r.Get(&d.seq) || !r.Get(&d.msg_id) || !r.Get(&d.send_utime) || !r.Get(&d.total_size) || !r.Get(&d.offset) ||
      !r.String(kMaxChannelBytes, &d.channel))
    return Fail(error, "truncated data frame");
  if (d.seq == 0) return Fail(error, "data frame with sequence number 0");
  if (!ValidChannelName(d.channel)) return Fail(error, "bad channel name");
  if (d.total_size > limits.max_message_bytes) return Fail(error, "message larger than max_message_bytes");
  uint32_t chunk_size = 0;
  if (!r.Get(&chunk_size)) return Fail(error, "truncated data frame");
  if (chunk_size > limits.max_chunk_bytes) return Fail(error, "chunk larger than the chunk limit");
  if (chunk_size != r.left()) return Fail(error, "chunk size does not match the frame");
  d.chunk = r.here();
  d.chunk_size = chunk_size;
  if (d.offset > d.total_size || d.chunk_size > d.total_size - d.offset)
    return Fail(error, "chunk outside its message");
  if (d.chunk_size == 0 && d.total_size != 0) return Fail(error, "empty chunk of a non-empty message");
  return true;
}

}  // namespace vloc::tunnel
