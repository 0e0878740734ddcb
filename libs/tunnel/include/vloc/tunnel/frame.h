#pragma once
// The tunnel's wire format: one ZeroMQ message per frame, little-endian.
//
//   header (16 bytes): magic "VLT1" | kind u8 | flags u8 | reserved u16 | session u64
//   DATA    body: seq u64 | msg_id u64 | send_utime i64 | total_size u32 | offset u32 |
//                 channel_len u8 | channel | chunk_size u32 | chunk
//   CONTROL body: acked_session u64 | acked_seq u64 | name_len u8 | name
//
// `session` is the sender's random id for its run: a restarted tunnel is a
// new session. DATA frames of a session are numbered 1, 2, ... and carry
// one chunk of one LCM message; CONTROL frames acknowledge (cumulatively)
// the peer's frames, and with kFlagRewind ask the peer to send again every
// frame after acked_seq (after a (re)connection or a gap).
// Every frame from the network is untrusted: DecodeFrame checks every size
// against the limits and returns false (with the reason) for anything else.

#include <cstdint>
#include <string>
#include <vector>

namespace vloc::tunnel {

inline constexpr uint32_t kMagic = 0x31544C56;  // "VLT1"
inline constexpr size_t kHeaderBytes = 16;
inline constexpr size_t kMaxChannelBytes = 63;  // LCM's channel name limit
inline constexpr size_t kMaxNameBytes = 64;
inline constexpr size_t kDataOverheadBytes = kHeaderBytes + 8 + 8 + 8 + 4 + 4 + 1 + kMaxChannelBytes + 4;

enum class FrameKind : uint8_t { kData = 1, kControl = 2 };
inline constexpr uint8_t kFlagRewind = 1;

struct DataFrame {
  uint64_t seq = 0;
  uint64_t msg_id = 0;
  int64_t send_utime = 0;  // us, wall clock, when the sending tunnel heard the message on its bus
  uint32_t total_size = 0;  // bytes of the whole LCM message
  uint32_t offset = 0;      // bytes, where this chunk starts in the message
  std::string channel;
  const uint8_t* chunk = nullptr;  // points into the decoded buffer
  size_t chunk_size = 0;
};

struct ControlFrame {
  uint64_t acked_session = 0;  // the peer session acknowledged (0: none heard yet)
  uint64_t acked_seq = 0;      // every DATA frame of that session up to this one arrived
  std::string name;            // the sender's name (for the operator)
};

struct Frame {
  FrameKind kind = FrameKind::kControl;
  uint8_t flags = 0;
  uint64_t session = 0;
  DataFrame data;
  ControlFrame control;
};

struct FrameLimits {
  size_t max_message_bytes = 64u << 20;  // largest LCM message (total_size)
  size_t max_chunk_bytes = 64u << 10;    // largest chunk in one DATA frame
};

std::vector<uint8_t> EncodeData(uint64_t session, const DataFrame& data);
std::vector<uint8_t> EncodeControl(uint64_t session, uint8_t flags, const ControlFrame& control);

// Decodes `size` bytes into *frame (whose data.chunk then points into
// `bytes`). False, with the reason in *error, for anything malformed.
bool DecodeFrame(const uint8_t* bytes, size_t size, const FrameLimits& limits, Frame* frame, std::string* error);

// LCM channel names the tunnel carries: 1-63 printable ASCII characters.
bool ValidChannelName(const std::string& channel);

}  // namespace vloc::tunnel
