#pragma once
/// @file
/// Visitors over the field lists of message_fields.hpp: distinctive sample values (to fill a
/// sample, or to check a decoded one against), the hand encoder, and the bounds a decoded
/// sample must keep whatever bytes it came from. Plus Sample<T>, a generated C sample that
/// frees its contents the way Cyclone allocates them.

#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>

#include <dds/dds.h>
#include <gtest/gtest.h>

#include "cdr_writer.hpp"
#include "message_fields.hpp"
#include "ros2_messages.hpp"

namespace ros2_messages_test {

template <class T>
const dds_topic_descriptor_t* descriptor() {
  return cartesian_impedance_ros2::MessageType<T>::descriptor();
}

/// A zero-initialized sample whose strings and sequences, allocated with dds_alloc by the test
/// or by Cyclone's deserializer, are freed by Cyclone's own dds_sample_free.
template <class T>
struct Sample {
  T value{};
  Sample() = default;
  ~Sample() { dds_sample_free(&value, descriptor<T>(), DDS_FREE_CONTENTS); }
  Sample(const Sample&) = delete;
  Sample& operator=(const Sample&) = delete;
};

/// Deterministic, distinctive values, one per field in visiting order: fill mode writes them into
/// a sample, check mode expects them in a (decoded) sample. No two consecutive fields of the same
/// type get the same value, strings have lengths 0 to 7 (so every padding case occurs after them)
/// and sequences have 1 to 3 elements (2 for sequences of structs).
class Values {
 public:
  enum class Mode { fill, check };
  explicit Values(Mode mode) : mode_(mode) {}

  template <class C>
  void boolean(C& m) {
    field(m, next() % 2 == 1);
  }
  template <class C>
  void uint8(C& m) {
    field(m, static_cast<uint8_t>(next() * 37 + 5));
  }
  template <class C>
  void int32(C& m) {
    field(m, static_cast<int32_t>(-1000003 * static_cast<int32_t>(next()) - 7));
  }
  template <class C>
  void uint32(C& m) {
    field(m, static_cast<uint32_t>(0x80000001u + 0x01010101u * (next() % 64)));
  }
  template <class C>
  void uint64(C& m) {
    field(m, static_cast<uint64_t>(0x0102030405060708ull * (next() % 200 + 1)));
  }
  template <class C>
  void float64(C& m) {
    const uint32_t k = next();
    field(m, (k % 2 == 1 ? -1.0 : 1.0) * (0.1 + 1.0625 * k));
  }
  void string(char*& m) {
    const uint32_t k = next();
    std::string expected((5 * k) % 8, ' ');
    for (size_t i = 0; i < expected.size(); ++i)
      expected[i] = static_cast<char>('a' + (k + i) % 26);
    if (mode_ == Mode::fill) {
      m = dds_string_dup(expected.c_str());
    } else {
      ASSERT_NE(m, nullptr) << "string #" << k;
      EXPECT_EQ(std::string(m), expected) << "string #" << k;
    }
  }
  /// A fixed array of octets (char[N] and uint8[N] in .msg): N distinct values.
  template <size_t N>
  void octet_array(uint8_t (&m)[N]) {
    const uint32_t k = next();
    for (size_t i = 0; i < N; ++i) {
      const auto expected = static_cast<uint8_t>(k * 31 + i * 7 + 1);
      if (mode_ == Mode::fill) {
        m[i] = expected;
      } else {
        EXPECT_EQ(m[i], expected) << "octet " << i << " of field #" << k;
      }
    }
  }
  /// A bounded string (string<=B in .msg), which idlc keeps in a char[B + 1].
  template <size_t N>
  void bounded_string(char (&m)[N]) {
    char* text = nullptr;
    if (mode_ == Mode::fill) {
      string(text);
      std::strncpy(m, text, N - 1);
      m[N - 1] = '\0';
      dds_free(text);
    } else {
      text = m;
      string(text);
    }
  }
  template <class S>
  void float64_seq(S& s) {
    sequence(s, 1 + next() % 3, [this](auto& element) { float64(element); });
  }
  template <class S>
  void string_seq(S& s) {
    sequence(s, 1 + next() % 3, [this](auto& element) { string(element); });
  }
  template <class T>
  void nested(T& m) {
    visit(*this, m);
  }
  template <class S>
  void nested_seq(S& s) {
    sequence(s, 2, [this](auto& element) { visit(*this, element); });
  }

 private:
  uint32_t next() { return counter_++; }

  template <class C, class T>
  void field(C& m, T expected) {
    if (mode_ == Mode::fill) {
      m = static_cast<C>(expected);
    } else {
      EXPECT_EQ(static_cast<T>(m), expected) << "field #" << counter_ - 1;
    }
  }
  template <class S, class F>
  void sequence(S& s, uint32_t n, F&& element) {
    using Element = std::remove_pointer_t<decltype(s._buffer)>;
    if (mode_ == Mode::fill) {
      s._buffer = static_cast<Element*>(dds_alloc(n * sizeof(Element)));
      std::memset(static_cast<void*>(s._buffer), 0, n * sizeof(Element));
      s._maximum = s._length = n;
      s._release = true;
    } else {
      EXPECT_EQ(s._length, n) << "sequence length, field #" << counter_ - 1;
      if (s._length < n) n = s._length;
    }
    for (uint32_t i = 0; i < n; ++i) element(s._buffer[i]);
  }

  Mode mode_;
  uint32_t counter_ = 0;
};

/// The hand encoder: writes each field as its .msg type says, in .msg order.
class Encoder {
 public:
  explicit Encoder(CdrWriter& w) : w_(w) {}

  template <class C>
  void boolean(C& m) {
    w_.boolean(static_cast<bool>(m));
  }
  template <class C>
  void uint8(C& m) {
    w_.octet(static_cast<uint8_t>(m));
  }
  template <class C>
  void int32(C& m) {
    w_.int32(static_cast<int32_t>(m));
  }
  template <class C>
  void uint32(C& m) {
    w_.uint32(static_cast<uint32_t>(m));
  }
  template <class C>
  void uint64(C& m) {
    w_.uint64(static_cast<uint64_t>(m));
  }
  template <class C>
  void float64(C& m) {
    w_.float64(static_cast<double>(m));
  }
  void string(char*& m) { w_.string(m == nullptr ? "" : m); }
  template <size_t N>
  void octet_array(uint8_t (&m)[N]) {
    for (const uint8_t octet : m) w_.octet(octet);  // no length: the size is the type's
  }
  template <size_t N>
  void bounded_string(char (&m)[N]) {
    w_.string(std::string(m, strnlen(m, N)));  // on the wire as any string
  }
  template <class S>
  void float64_seq(S& s) {
    w_.sequence_length(s._length);
    for (uint32_t i = 0; i < s._length; ++i) float64(s._buffer[i]);
  }
  template <class S>
  void string_seq(S& s) {
    w_.sequence_length(s._length);
    for (uint32_t i = 0; i < s._length; ++i) string(s._buffer[i]);
  }
  template <class T>
  void nested(T& m) {
    visit(*this, m);
  }
  template <class S>
  void nested_seq(S& s) {
    w_.sequence_length(s._length);
    for (uint32_t i = 0; i < s._length; ++i) visit(*this, s._buffer[i]);
  }

 private:
  CdrWriter& w_;
};

template <class T>
CdrWriter hand_encode(T& sample) {
  CdrWriter w;
  Encoder encoder(w);
  visit(encoder, sample);
  return w;
}

/// What a decoded sample must satisfy whatever bytes it came from: every string and sequence
/// fits in the received bytes (a count can only be honoured if its elements were there: 8 bytes
/// a double, 5 a string, at least 1 anything else) and every element is readable. Reading each
/// one makes AddressSanitizer see any buffer Cyclone got wrong.
class Bounds {
 public:
  explicit Bounds(size_t received) : received_(received) {}

  template <class C>
  void boolean(C& m) {
    unsigned char raw;  // not read as bool: any byte value may have been received
    std::memcpy(&raw, &m, 1);
    sink_ += raw;
  }
  template <class C>
  void uint8(C& m) {
    sink_ += static_cast<double>(m);
  }
  template <class C>
  void int32(C& m) {
    sink_ += static_cast<double>(m);
  }
  template <class C>
  void uint32(C& m) {
    sink_ += static_cast<double>(m);
  }
  template <class C>
  void uint64(C& m) {
    sink_ += static_cast<double>(m);
  }
  template <class C>
  void float64(C& m) {
    uint64_t bits;  // NaN and infinities are valid doubles on the wire
    std::memcpy(&bits, &m, sizeof bits);
    sink_ += static_cast<double>(bits & 0xff);
  }
  void string(char*& m) {
    ASSERT_NE(m, nullptr);
    EXPECT_LT(std::strlen(m), received_);
  }
  template <size_t N>
  void octet_array(uint8_t (&m)[N]) {
    for (const uint8_t octet : m) sink_ += octet;
  }
  template <size_t N>
  void bounded_string(char (&m)[N]) {
    EXPECT_LT(strnlen(m, N), N) << "a bounded string without its terminating NUL";
  }
  template <class S>
  void float64_seq(S& s) {
    sequence(s, 8, [this](auto& element) { float64(element); });
  }
  template <class S>
  void string_seq(S& s) {
    sequence(s, 5, [this](auto& element) { string(element); });
  }
  template <class T>
  void nested(T& m) {
    visit(*this, m);
  }
  template <class S>
  void nested_seq(S& s) {
    sequence(s, 1, [this](auto& element) { visit(*this, element); });
  }

  double sink() const { return sink_; }

 private:
  template <class S, class F>
  void sequence(S& s, size_t wire_size, F&& element) {
    EXPECT_LE(s._length, s._maximum);
    EXPECT_LE(s._length * wire_size, received_);
    if (s._length > 0) {
      ASSERT_NE(s._buffer, nullptr);
    }
    if (s._length * wire_size > received_) return;
    for (uint32_t i = 0; i < s._length; ++i) element(s._buffer[i]);
  }

  size_t received_;
  double sink_ = 0;
};

}  // namespace ros2_messages_test
