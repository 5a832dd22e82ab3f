// Malformed input for the types the node receives: Cyclone's deserializer must reject it or decode
// it into a sample that stays within what was received, and never crash (also run under
// AddressSanitizer: CARTESIAN_IMPEDANCE_SANITIZE=address).
//
// How Cyclone 0.10.2 validates (ddsi_serdata_default.c, ddsi_cdrstream.c; the identifier cases
// identifiers checked by
// EncapsulationsOtherThanPlainCdrAreRejected): from_ser_iov refuses input shorter than the 4-byte
// encapsulation header and any identifier but the plain encodings of a @final type (CDR_LE/BE, and
// CDR2_LE/BE: PL_CDR, D_CDR2 and unknown ones are refused), drops the number of padding bytes the
// options announce, then runs dds_stream_normalize over the payload before anything is decoded.
// normalize walks the type's serialization ops with the payload size as the bound: each primitive
// must fit after its alignment; a string's length must be non-zero, fit in the remaining bytes and
// end on a NUL; a sequence count must fit (count * element size for primitives, element by element
// for strings and structs, so a huge count fails at the first missing element, before any
// allocation); and it byte-swaps in place for big-endian input. It stops at the first violation,
// and only normalized data reaches dds_stream_read (to_sample), which then trusts it. What
// normalize does not check: bytes after the last field (accepted and ignored), the values (any
// double, NaN included), and which representation the identifier names (CDR2_LE is read as XCDR2
// even by an XCDR1-only reader: the data representation QoS is matched at discovery, not per
// sample).

#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "cyclone_codec.hpp"
#include "message_types.hpp"
#include "sample_values.hpp"

namespace ros2_messages_test {
namespace {

template <class T>
class Malformed : public ::testing::Test {
 protected:
  void SetUp() override {
    type_ = sertype_of(descriptor<T>());
    ASSERT_NE(type_, nullptr);
    Sample<T> sample;
    Values fill(Values::Mode::fill);
    visit(fill, sample.value);
    const CdrWriter writer = hand_encode(sample.value);
    golden_ = writer.bytes();
    length_offsets_ = writer.length_offsets();
  }

  // True if Cyclone accepted the bytes; then the decoded sample must be within bounds.
  bool decode(const std::vector<uint8_t>& bytes) {
    Sample<T> sample;
    if (!cyclone_deserialize(type_, bytes, &sample.value)) return false;
    Bounds bounds(bytes.size());
    visit(bounds, sample.value);
    return true;
  }

  const ddsi_sertype* type_ = nullptr;
  std::vector<uint8_t> golden_;
  std::vector<size_t> length_offsets_;
};
TYPED_TEST_SUITE(Malformed, ReceivedMessages, RosNames);

void put_uint32(std::vector<uint8_t>& bytes, size_t offset, uint32_t v) {
  for (size_t i = 0; i < 4; ++i) bytes[offset + i] = static_cast<uint8_t>(v >> (8 * i));
}

TYPED_TEST(Malformed, TheGoldenSampleIsAccepted) {
  EXPECT_TRUE(this->decode(this->golden_));
}

// Parameter-list and delimited encapsulations (PL_CDR_BE/LE 0x0002/3, PL_CDR2 0x000a/b, D_CDR2
// 0x0008/9) do not fit a @final type, and unknown identifiers (XCDR1 header bytes swapped) mean
// nothing; CDR2_LE (0x0007) is accepted and read as XCDR2, which must stay in bounds too.
TYPED_TEST(Malformed, EncapsulationsOtherThanPlainCdrAreRejected) {
  for (uint16_t identifier : {0x0002, 0x0003, 0x0008, 0x0009, 0x000a, 0x000b, 0x0100, 0xffff}) {
    std::vector<uint8_t> bytes = this->golden_;
    bytes[0] = static_cast<uint8_t>(identifier >> 8);
    bytes[1] = static_cast<uint8_t>(identifier);
    EXPECT_FALSE(this->decode(bytes)) << "identifier " << identifier;
  }
  std::vector<uint8_t> xcdr2 = this->golden_;
  xcdr2[1] = 0x07;
  this->decode(xcdr2);
}

// Every prefix short of the last field's end lacks at least one byte of a field (the hand
// encoder's final padding is announced in the options, and Cyclone drops it before validating).
// What only the padding is missing from (std_msgs/Empty's one octet, padded to 4) holds every
// field and may be read.
TYPED_TEST(Malformed, EveryTruncationIsRejected) {
  const size_t padding = this->golden_[3] & 0x3u;
  for (size_t n = 0; n + padding < this->golden_.size(); ++n) {
    const std::vector<uint8_t> prefix(this->golden_.begin(), this->golden_.begin() + n);
    EXPECT_FALSE(this->decode(prefix)) << n << " of " << this->golden_.size() << " bytes";
  }
}

// A count or length that the received bytes cannot hold, at every string length and sequence
// count of the sample: 2^32 - 1 and 2^31 (the values an unchecked int32 conversion turns
// negative, or an unchecked allocation turns into gigabytes).
TYPED_TEST(Malformed, HugeLengthsAreRejected) {
  if (this->length_offsets_.empty()) GTEST_SKIP() << "no string or sequence in this type";
  for (size_t offset : this->length_offsets_) {
    for (uint32_t length : {0xFFFFFFFFu, 0x80000000u, 0x7FFFFFFFu}) {
      std::vector<uint8_t> bytes = this->golden_;
      put_uint32(bytes, offset, length);
      EXPECT_FALSE(this->decode(bytes))
          << "length " << length << " at payload offset " << offset - 4;
    }
  }
}

// Lengths off by a little: zero (an empty sequence is valid, a zero string length is not), one
// less or one more than written. Either outcome is allowed; the sample must stay in bounds.
TYPED_TEST(Malformed, NearbyLengthsAreRejectedOrBounded) {
  for (size_t offset : this->length_offsets_) {
    const uint32_t written = static_cast<uint32_t>(this->golden_[offset]) |
                             static_cast<uint32_t>(this->golden_[offset + 1]) << 8;
    for (uint32_t length : {0u, written - 1, written + 1}) {
      std::vector<uint8_t> bytes = this->golden_;
      put_uint32(bytes, offset, length);
      this->decode(bytes);
    }
  }
}

// Seeded random damage (the same on every run): overwritten bytes anywhere (header included), a
// random count at a length field, truncation, trailing garbage, and combinations.
TYPED_TEST(Malformed, RandomMutationsAreRejectedOrBounded) {
  std::mt19937 random(20240611u + static_cast<uint32_t>(this->golden_.size()));
  auto uniform = [&random](size_t n) {
    return std::uniform_int_distribution<size_t>(0, n - 1)(random);
  };
  int accepted = 0;
  int rejected = 0;
  for (int i = 0; i < 3000; ++i) {
    std::vector<uint8_t> bytes = this->golden_;
    const size_t kind = uniform(4);
    if (kind == 0 || kind == 3) {
      for (size_t n = 1 + uniform(4); n > 0; --n)
        bytes[uniform(bytes.size())] = static_cast<uint8_t>(random());
    }
    if (kind == 1 && this->length_offsets_.empty()) {
      bytes[uniform(bytes.size())] ^= 0xff;
    } else if (kind == 1) {
      const uint32_t value = random() >> uniform(32);  // small counts as often as huge ones
      put_uint32(bytes, this->length_offsets_[uniform(this->length_offsets_.size())], value);
    }
    if (kind == 2) bytes.resize(uniform(bytes.size()));
    if (kind == 3) {
      for (size_t n = uniform(16); n > 0; --n) bytes.push_back(static_cast<uint8_t>(random()));
    }
    (this->decode(bytes) ? accepted : rejected)++;
    if (::testing::Test::HasFatalFailure()) return;
  }
  // Both outcomes occur: the mutations reach the validation, and not everything is refused.
  EXPECT_GT(accepted, 0);
  EXPECT_GT(rejected, 0);
  ::testing::Test::RecordProperty("accepted", accepted);
  ::testing::Test::RecordProperty("rejected", rejected);
}

}  // namespace
}  // namespace ros2_messages_test
