#pragma once
/// @file
/// A hand-written XCDR1 little-endian encoder, the reference the tests hold Cyclone's serializer
/// to. It knows the wire rules and nothing of the generated code:
/// - a 4-byte encapsulation header: identifier CDR_LE (00 01), then the options (big-endian
///   uint16);
/// - each primitive aligned to its size (1 for bool/octet, 4 for int32/uint32 and every length, 8
///   for int64/uint64/double), measured from the end of the header;
/// - a string is a uint32 length that counts the terminating NUL, the characters, the NUL;
/// - a sequence is a uint32 element count, then the elements;
/// - the payload is padded with zeros to a multiple of 4 and the two low bits of the options give
///   the number of padding bytes (DDS-XTypes 1.3, 7.6.3.1.2). Cyclone writes this padding; a
///   reader that ignores the options field (Fast-CDR) reads the same values.

#include <cstdint>
#include <cstring>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

namespace ros2_messages_test {

class CdrWriter {
 public:
  CdrWriter() : bytes_{0x00, 0x01, 0x00, 0x00} {}

  void boolean(bool v) { put(v ? 1u : 0u, 1); }
  void octet(uint8_t v) { put(v, 1); }
  void int32(int32_t v) { put(static_cast<uint32_t>(v), 4); }
  void uint32(uint32_t v) { put(v, 4); }
  void int64(int64_t v) { put(static_cast<uint64_t>(v), 8); }
  void uint64(uint64_t v) { put(v, 8); }
  void float64(double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    put(bits, 8);
  }
  void string(const std::string& v) {
    length(static_cast<uint32_t>(v.size() + 1));
    bytes_.insert(bytes_.end(), v.begin(), v.end());
    bytes_.push_back(0);
  }
  /// The element count of a sequence.
  void sequence_length(uint32_t n) { length(n); }

  /// The encoded sample: header, payload, final padding.
  std::vector<uint8_t> bytes() const {
    std::vector<uint8_t> out = bytes_;
    const size_t padding = (4 - (out.size() - kHeader) % 4) % 4;
    out.insert(out.end(), padding, 0);
    out[3] = static_cast<uint8_t>(padding);
    return out;
  }
  /// Offsets (in bytes()) of every string length and sequence count written, for the tests that
  /// corrupt them.
  const std::vector<size_t>& length_offsets() const { return length_offsets_; }

 private:
  static constexpr size_t kHeader = 4;

  void length(uint32_t n) {
    align(4);
    length_offsets_.push_back(bytes_.size());
    put(n, 4);
  }
  void align(size_t n) {
    while ((bytes_.size() - kHeader) % n != 0) bytes_.push_back(0);
  }
  void put(uint64_t v, size_t size) {
    align(size);
    for (size_t i = 0; i < size; ++i) bytes_.push_back(static_cast<uint8_t>(v >> (8 * i)));
  }

  std::vector<uint8_t> bytes_;
  std::vector<size_t> length_offsets_;
};

// One line per 8 bytes, with the offset from the start of the payload (after the 4-byte
// encapsulation header), so a failure shows where the two encodings part.
inline std::string hex(const std::vector<uint8_t>& bytes) {
  std::ostringstream out;
  out << std::hex << std::setfill('0');
  for (size_t i = 0; i < bytes.size(); ++i) {
    if (i == 4 || (i > 4 && (i - 4) % 8 == 0)) out << "\n" << std::setw(4) << i - 4 << ":";
    if (i == 0) out << "hdr:";
    out << " " << std::setw(2) << static_cast<int>(bytes[i]);
  }
  return out.str();
}

}  // namespace ros2_messages_test
