#pragma once
/// @file
/// Raw payloads on the wire: a TopicDataType that writes whatever bytes it is given under a real
/// type's name (so the node's reader matches it and has to parse them), the generator of
/// malformed samples derived from a valid one, and a genuine XCDR2 PoseStamped.

#include <array>
#include <cstdint>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <random>
#include <string>
#include <vector>

namespace fastdds_peer {

using Bytes = std::vector<unsigned char>;

/// A type named `dds_name` whose samples are Bytes, written verbatim: the first four bytes are
/// the encapsulation header.
class RawType final : public eprosima::fastdds::dds::TopicDataType {
 public:
  explicit RawType(const std::string& dds_name);
  bool serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) override;
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override;
  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override;
  void* createData() override;
  void deleteData(void* data) override;
  bool getKey(void* data, eprosima::fastrtps::rtps::InstanceHandle_t* handle,
              bool force_md5) override;
};

/// How a malformed sample differs from the valid one.
enum class Mutation {
  truncated,       ///< cut short at a random length
  huge_length,     ///< an aligned 32-bit word (string or sequence lengths among them) set to
                   ///< 0xFFFFFFFF, 0x80000000, 0, one past the payload, ...
  random_bytes,    ///< a few bytes replaced at random
  special_double,  ///< an aligned 8-byte word set to NaN, infinity, 1e308, a denormal, ...
  garbage,         ///< random bytes of random length after the header
  trailing,        ///< the valid sample followed by random bytes
  header_only,     ///< the encapsulation header and nothing else
  count_           ///< number of kinds
};
const char* name(Mutation mutation);

/// Malformed variants of `valid` (header included), reproducible from `seed`. Every variant keeps
/// the XCDR1 little-endian encapsulation header 00 01 00 00, so receivers must parse the body.
class Fuzzer {
 public:
  Fuzzer(Bytes valid, std::uint64_t seed);
  Bytes next(Mutation* kind);

 private:
  std::uint64_t below(std::uint64_t bound) { return engine_() % bound; }
  std::size_t aligned_offset(std::size_t size, std::size_t alignment);

  Bytes valid_;
  std::mt19937_64 engine_;  // fully specified by the standard: the same seed, the same samples
};

/// geometry_msgs/msg/PoseStamped in XCDR2 (PLAIN_CDR2, little-endian, encapsulation 00 07): a
/// final struct has no DHEADER, 8-byte values align to 4 instead of 8.
Bytes xcdr2_pose_stamped(double stamp, const std::string& frame_id,
                         const std::array<double, 7>& pose);

}  // namespace fastdds_peer
