#include "peer_fuzz.hpp"

#include <fastdds/rtps/common/SerializedPayload.h>
#include <cmath>
#include <cstring>
#include <limits>

namespace fastdds_peer {

namespace {

constexpr std::size_t kHeader = 4;

void put_u32(Bytes& out, std::size_t offset, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) {
    out[offset + i] = static_cast<unsigned char>(value >> (8 * i));
  }
}

void put_f64(Bytes& out, std::size_t offset, double value) {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &value, sizeof bits);
  for (int i = 0; i < 8; ++i) {
    out[offset + i] = static_cast<unsigned char>(bits >> (8 * i));
  }
}

}  // namespace

// ---- RawType ------------------------------------------------------------------------------------

RawType::RawType(const std::string& dds_name) {
  setName(dds_name.c_str());
  // Only the initial payload reservation: writers use PREALLOCATED_WITH_REALLOC.
  m_typeSize = 1024;
  m_isGetKeyDefined = false;
}

bool RawType::serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) {
  const auto& bytes = *static_cast<const Bytes*>(data);
  if (bytes.size() > payload->max_size) {
    return false;
  }
  std::memcpy(payload->data, bytes.data(), bytes.size());
  payload->length = static_cast<std::uint32_t>(bytes.size());
  payload->encapsulation = CDR_LE;
  return true;
}

bool RawType::deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) {
  static_cast<Bytes*>(data)->assign(payload->data, payload->data + payload->length);
  return true;
}

std::function<std::uint32_t()> RawType::getSerializedSizeProvider(void* data) {
  return [data] { return static_cast<std::uint32_t>(static_cast<Bytes*>(data)->size()); };
}

void* RawType::createData() {
  return new Bytes();
}

void RawType::deleteData(void* data) {
  delete static_cast<Bytes*>(data);
}

bool RawType::getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) {
  return false;
}

// ---- Fuzzer -------------------------------------------------------------------------------------

const char* name(Mutation mutation) {
  switch (mutation) {
    case Mutation::truncated:
      return "truncated";
    case Mutation::huge_length:
      return "huge_length";
    case Mutation::random_bytes:
      return "random_bytes";
    case Mutation::special_double:
      return "special_double";
    case Mutation::garbage:
      return "garbage";
    case Mutation::trailing:
      return "trailing";
    case Mutation::header_only:
      return "header_only";
    case Mutation::count_:
      break;
  }
  return "?";
}

Fuzzer::Fuzzer(Bytes valid, std::uint64_t seed) : valid_(std::move(valid)), engine_(seed) {
  valid_.resize(std::max(valid_.size(), kHeader));
  // XCDR1, little-endian, no options: what every variant claims to be.
  valid_[0] = 0x00, valid_[1] = 0x01, valid_[2] = 0x00, valid_[3] = 0x00;
}

// An offset in the body aligned as XCDR1 aligns values (from the end of the header), with room
// for `alignment` bytes; kHeader if the body is too short.
std::size_t Fuzzer::aligned_offset(std::size_t size, std::size_t alignment) {
  if (size < kHeader + alignment) {
    return kHeader;
  }
  const std::size_t slots = (size - kHeader - alignment) / alignment + 1;
  return kHeader + alignment * below(slots);
}

Bytes Fuzzer::next(Mutation* kind) {
  *kind = static_cast<Mutation>(below(static_cast<std::uint64_t>(Mutation::count_)));
  Bytes out = valid_;
  const std::size_t body = valid_.size() - kHeader;
  switch (*kind) {
    case Mutation::truncated:
      out.resize(kHeader + (body > 0 ? below(body) : 0));
      break;
    case Mutation::huge_length: {
      const std::uint32_t lengths[] = {0xFFFFFFFFu,
                                       0x80000000u,
                                       0x7FFFFFFFu,
                                       0x10000000u,
                                       0xFFFFFFF0u,
                                       0u,
                                       static_cast<std::uint32_t>(body + 1)};
      if (body < 4) {
        out.resize(kHeader + 4);
      }
      const std::uint64_t words = 1 + below(2);
      for (std::uint64_t i = 0; i < words; ++i) {
        put_u32(out, aligned_offset(out.size(), 4), lengths[below(std::size(lengths))]);
      }
      break;
    }
    case Mutation::random_bytes:
      if (body == 0) {
        out.push_back(0);
      }
      for (std::uint64_t i = 0, n = 1 + below(8); i < n; ++i) {
        out[kHeader + below(out.size() - kHeader)] = static_cast<unsigned char>(engine_());
      }
      break;
    case Mutation::special_double: {
      const double values[] = {std::numeric_limits<double>::quiet_NaN(),
                               std::numeric_limits<double>::infinity(),
                               -std::numeric_limits<double>::infinity(),
                               1e308,
                               -1e308,
                               std::numeric_limits<double>::denorm_min(),
                               -0.0,
                               1e6};
      if (body < 8) {
        out.resize(kHeader + 8);
      }
      put_f64(out, aligned_offset(out.size(), 8), values[below(std::size(values))]);
      break;
    }
    case Mutation::garbage:
      out.resize(kHeader + below(257));
      for (std::size_t i = kHeader; i < out.size(); ++i) {
        out[i] = static_cast<unsigned char>(engine_());
      }
      break;
    case Mutation::trailing:
      for (std::uint64_t i = 0, n = 1 + below(64); i < n; ++i) {
        out.push_back(static_cast<unsigned char>(engine_()));
      }
      break;
    case Mutation::header_only:
    case Mutation::count_:
      out.resize(kHeader);
      break;
  }
  return out;
}

// ---- XCDR2 --------------------------------------------------------------------------------------

Bytes xcdr2_pose_stamped(double stamp, const std::string& frame_id,
                         const std::array<double, 7>& pose) {
  const auto align4 = [](std::size_t n) { return (n + 3) / 4 * 4; };
  const std::size_t string_end = 8 + 4 + frame_id.size() + 1;
  Bytes out(kHeader + align4(string_end) + 8 * pose.size(), 0);
  out[1] = 0x07;  // PLAIN_CDR2, little-endian
  const double seconds = std::floor(stamp);
  put_u32(out, kHeader, static_cast<std::uint32_t>(static_cast<std::int32_t>(seconds)));
  put_u32(out, kHeader + 4, static_cast<std::uint32_t>((stamp - seconds) * 1e9));
  put_u32(out, kHeader + 8, static_cast<std::uint32_t>(frame_id.size() + 1));
  std::memcpy(&out[kHeader + 12], frame_id.data(), frame_id.size());
  std::size_t offset = kHeader + align4(string_end);
  for (const double value : pose) {
    put_f64(out, offset, value);
    offset += 8;
  }
  return out;
}

}  // namespace fastdds_peer
