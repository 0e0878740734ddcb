#pragma once
// Hostile LCM messages for robustness tests: what a radio link, a logger of
// an older build or a broken driver can put on the bus. Each case has a
// name that says what it is and fixes its bytes (random cases are seeded by
// a hash of their name), so a failing case can be rebuilt from the test
// output alone:
//   <channel>:random:<k>            random bytes, half with the right fingerprint
//   <channel>:truncate:<k>          the template cut short
//   <channel>:extend:<k>            the template with random bytes appended
//   <channel>:wrong-type:<type>     a valid message of another type
//   <channel>:extreme:<field>=<v>   one number or string length set to an extreme
//   <channel>:time:<shift>          the template's utime moved (backwards, far ahead)
// Header-only.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "vloc/lcm_io/lcm_schema.h"

namespace vloc::testing {

struct HostileMessage {
  std::string name;
  std::vector<uint8_t> bytes;
};

// FNV-1a: a stable hash of a case name (std::hash is not stable).
inline uint64_t CaseSeed(const std::string& name) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : name) h = (h ^ c) * 1099511628211ull;
  return h;
}

namespace hostile_detail {

inline void PutBigEndian(std::vector<uint8_t>* b, size_t at, uint64_t v, size_t size) {
  for (size_t k = 0; k < size; ++k) (*b)[at + k] = static_cast<uint8_t>(v >> (8 * (size - 1 - k)));
}
inline uint64_t GetBigEndian(const std::vector<uint8_t>& b, size_t at, size_t size) {
  uint64_t v = 0;
  for (size_t k = 0; k < size; ++k) v = (v << 8) | b[at + k];
  return v;
}

// Extreme values for one span, as (label, raw big-endian value).
inline std::vector<std::pair<std::string, uint64_t>> Extremes(const LcmFieldSpan& span) {
  std::vector<std::pair<std::string, uint64_t>> out;
  auto as_double = [](double d) {
    uint64_t u;
    std::memcpy(&u, &d, 8);
    return u;
  };
  auto as_float = [](float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return static_cast<uint64_t>(u);
  };
  if (span.kind == LcmFieldSpan::Kind::kStringLength) {
    for (uint32_t v : {0x80000000u, 0xFFFFFFFFu, 0u, 0x7FFFFFFFu}) out.push_back({std::to_string(v), v});
    return out;
  }
  if (span.type == "double") {
    const double inf = std::numeric_limits<double>::infinity();
    for (double d : {std::nan(""), inf, -inf, 1e308, -1e308}) out.push_back({std::to_string(d), as_double(d)});
  } else if (span.type == "float") {
    const float inf = std::numeric_limits<float>::infinity();
    for (float f : {std::nanf(""), inf, -inf, 3e38f, -3e38f}) out.push_back({std::to_string(f), as_float(f)});
  } else if (span.size > 1) {
    const uint64_t bits = 8 * span.size;
    const uint64_t mask = bits == 64 ? ~0ull : (1ull << bits) - 1;
    out.push_back({"min", (1ull << (bits - 1)) & mask});
    out.push_back({"max", ((1ull << (bits - 1)) - 1) & mask});
    out.push_back({"-1", mask});
  } else {  // int8_t, byte, boolean
    out.push_back({"min", 0x80});
    out.push_back({"max", 0x7F});
    out.push_back({"-1", 0xFF});
  }
  return out;
}

}  // namespace hostile_detail

// Up to `budget` hostile variants of `templ` (the bytes of one valid
// message of `type`) for `channel` (a label: it seeds the choice, so give
// each template its own, e.g. "IMU#17"), drawn from every kind above.
// `others`: valid messages of other types, for the wrong-type cases.
// `utime_shift_us`: shifts for the time cases (0 = none).
inline std::vector<HostileMessage> MakeHostileMessages(const std::string& channel, const std::string& type,
                                                       const std::vector<uint8_t>& templ,
                                                       const std::vector<std::vector<uint8_t>>& others, int budget,
                                                       const std::vector<int64_t>& utime_shift_us = {
                                                           -1, -3600000000, 3600000000}) {
  using namespace hostile_detail;
  const LcmSchema& schema = LcmSchema::Vloc();
  std::vector<HostileMessage> extreme, rest;
  const std::string prefix = channel + ":";
  // Extremes of every number and string length (first elements of arrays).
  for (const LcmFieldSpan& span : schema.Spans(type, templ.data(), templ.size())) {
    for (const auto& [label, raw] : Extremes(span)) {
      HostileMessage m{prefix + "extreme:" + span.path + "=" + label, templ};
      PutBigEndian(&m.bytes, span.offset, raw, span.size);
      extreme.push_back(std::move(m));
    }
  }
  // Time: the first field named utime, moved.
  for (const LcmFieldSpan& span : schema.Spans(type, templ.data(), templ.size(), 1)) {
    if (span.path != "utime" || span.size != 8) continue;
    for (int64_t shift : utime_shift_us) {
      if (shift == 0) continue;
      HostileMessage m{prefix + "time:" + std::to_string(shift), templ};
      const int64_t t = static_cast<int64_t>(GetBigEndian(templ, span.offset, 8));
      PutBigEndian(&m.bytes, span.offset, static_cast<uint64_t>(t + shift), 8);
      rest.push_back(std::move(m));
    }
    break;
  }
  for (size_t k = 0; k < others.size(); ++k) rest.push_back({prefix + "wrong-type:" + std::to_string(k), others[k]});
  // Random, truncated and extended: seeded by the name.
  const int random_cases = std::max(2, budget / 6);
  for (int k = 0; k < random_cases; ++k) {
    for (const char* kind : {"random", "truncate", "extend"}) {
      HostileMessage m{prefix + kind + ":" + std::to_string(k), {}};
      std::mt19937_64 rng(CaseSeed(m.name));
      if (std::string(kind) == "random") {
        m.bytes.resize(rng() % (2 * templ.size() + 16));
        for (auto& b : m.bytes) b = static_cast<uint8_t>(rng());
        if (k % 2 == 0 && m.bytes.size() >= 8) std::memcpy(m.bytes.data(), templ.data(), 8);  // right fingerprint
      } else if (std::string(kind) == "truncate") {
        m.bytes.assign(templ.begin(), templ.begin() + static_cast<long>(rng() % templ.size()));
      } else {
        m.bytes = templ;
        const size_t extra = 1 + rng() % 64;
        for (size_t i = 0; i < extra; ++i) m.bytes.push_back(static_cast<uint8_t>(rng()));
      }
      rest.push_back(std::move(m));
    }
  }
  // Keep the budget: a shuffle seeded by the channel label, so the kinds mix.
  std::vector<HostileMessage> out = std::move(rest);
  for (auto& m : extreme) out.push_back(std::move(m));
  std::mt19937_64 rng(CaseSeed(channel));
  std::shuffle(out.begin(), out.end(), rng);
  if (static_cast<int>(out.size()) > budget) out.resize(static_cast<size_t>(std::max(0, budget)));
  return out;
}

}  // namespace vloc::testing
