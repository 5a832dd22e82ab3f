// Golden CDR bytes: for every generated type, Cyclone's serializer must write exactly what the
// hand encoder (cdr_writer.hpp, driven by the .msg field lists of message_fields.hpp) writes, and
// Cyclone's deserializer must read those bytes back into the values they were made from. Plus the
// descriptors' DDS type names, on which ROS 2's DDS layers match.

#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cyclone_codec.hpp"
#include "message_types.hpp"
#include "sample_values.hpp"

namespace ros2_messages_test {
namespace {

// The reference itself, against bytes worked out by hand from the rules in cdr_writer.hpp: a
// PoseStamped-like run (int32, uint32, string, then a double that must skip to an 8-byte offset),
// a sequence, a bool, a uint64 after it, and the final padding announced in the options.
// Length offsets count from the start, header included.
TEST(GoldenCdrWriter, WritesXcdr1AsSpecified) {
  CdrWriter w;
  w.int32(-2);
  w.uint32(7);
  w.string("abcde");
  w.float64(1.0);
  w.sequence_length(1);
  w.string("");
  w.boolean(true);
  w.uint64(0x0102030405060708ull);
  w.boolean(false);
  const std::vector<uint8_t> expected = {
      0x00, 0x01, 0x00, 0x03,                          // CDR_LE, 3 bytes of final padding
      0xfe, 0xff, 0xff, 0xff, 0x07, 0x00, 0x00, 0x00,  // 0: -2, 7
      0x06, 0x00, 0x00, 0x00, 'a',  'b',  'c',  'd',   // 8: length 6 incl. NUL
      'e',  0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 16: ..., pad to 24
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf0, 0x3f,  // 24: 1.0
      0x01, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00,  // 32: 1 element, "" is length 1
      0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 40: NUL, true, pad to 48
      0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01,  // 48: uint64
      0x00, 0x00, 0x00, 0x00};                         // 56: false, 3 bytes of padding
  EXPECT_EQ(hex(w.bytes()), hex(expected));
  EXPECT_EQ(w.length_offsets(), (std::vector<size_t>{12, 36, 40}));
}

template <class T>
class GoldenCdr : public ::testing::Test {};
TYPED_TEST_SUITE(GoldenCdr, AllMessages, RosNames);

TYPED_TEST(GoldenCdr, CycloneWritesTheHandEncodedBytes) {
  Sample<TypeParam> sample;
  Values fill(Values::Mode::fill);
  visit(fill, sample.value);
  const std::vector<uint8_t> expected = hand_encode(sample.value).bytes();

  const ddsi_sertype* type = sertype_of(descriptor<TypeParam>());
  ASSERT_NE(type, nullptr);
  EXPECT_EQ(hex(cyclone_serialize(type, &sample.value)), hex(expected));
}

TYPED_TEST(GoldenCdr, CycloneReadsTheHandEncodedBytes) {
  std::vector<uint8_t> golden;
  {
    Sample<TypeParam> sample;
    Values fill(Values::Mode::fill);
    visit(fill, sample.value);
    golden = hand_encode(sample.value).bytes();
  }
  const ddsi_sertype* type = sertype_of(descriptor<TypeParam>());
  ASSERT_NE(type, nullptr);
  Sample<TypeParam> decoded;
  ASSERT_TRUE(cyclone_deserialize(type, golden, &decoded.value)) << hex(golden);
  Values check(Values::Mode::check);
  visit(check, decoded.value);
}

// Without the final padding (options 0, as Fast-CDR writes), the same values: a reader must not
// depend on it.
TYPED_TEST(GoldenCdr, CycloneReadsUnpaddedBytes) {
  std::vector<uint8_t> golden;
  {
    Sample<TypeParam> sample;
    Values fill(Values::Mode::fill);
    visit(fill, sample.value);
    golden = hand_encode(sample.value).bytes();
  }
  golden.resize(golden.size() - golden[3]);
  golden[3] = 0;
  const ddsi_sertype* type = sertype_of(descriptor<TypeParam>());
  ASSERT_NE(type, nullptr);
  Sample<TypeParam> decoded;
  ASSERT_TRUE(cyclone_deserialize(type, golden, &decoded.value)) << hex(golden);
  Values check(Values::Mode::check);
  visit(check, decoded.value);
}

template <class... Ts>
std::set<std::string> ros_names(::testing::Types<Ts...>*) {
  return {cartesian_impedance_ros2::MessageType<Ts>::ros_name...};
}

template <class T>
class Descriptor : public ::testing::Test {};
TYPED_TEST_SUITE(Descriptor, AllMessages, RosNames);

// ROS 2's DDS mapping of pkg/msg/Name, derived here from the ROS name alone.
TYPED_TEST(Descriptor, TypeNameIsRos2sDdsName) {
  const std::string ros_name = cartesian_impedance_ros2::MessageType<TypeParam>::ros_name;
  const size_t slash = ros_name.find("/msg/");
  ASSERT_NE(slash, std::string::npos) << ros_name;
  const std::string package = ros_name.substr(0, slash);
  const std::string name = ros_name.substr(slash + 5);
  EXPECT_STREQ(descriptor<TypeParam>()->m_typename,
               (package + "::msg::dds_::" + name + "_").c_str());
}

// The type lists above name every type the generator produced, so the golden test misses none,
// except the parameter services' messages (rcl_interfaces, and service_msgs for their hashes
// only): their wire form, header included, is checked by ros2_parameter_services_tests
// (ParameterServicesGolden), on one request and one reply that reach every one of their fields
// the node reads or writes.
TEST(GoldenCdrCoverage, EveryGeneratedTypeIsTested) {
  std::ifstream json(CARTESIAN_IMPEDANCE_ROS2_HASHES);
  ASSERT_TRUE(json) << CARTESIAN_IMPEDANCE_ROS2_HASHES;
  std::stringstream text;
  text << json.rdbuf();
  const std::string content = text.str();
  // The json's keys: the ROS names, each followed by its object.
  std::set<std::string> generated;
  for (size_t at = content.find("/msg/"); at != std::string::npos;
       at = content.find("/msg/", at + 1)) {
    const size_t open = content.rfind('"', at);
    const size_t close = content.find('"', at);
    const std::string name = content.substr(open + 1, close - open - 1);
    if (content.compare(close, 4, "\": {") == 0 && name.rfind("rcl_interfaces/", 0) != 0 &&
        name.rfind("service_msgs/", 0) != 0)
      generated.insert(name);
  }
  const std::set<std::string> tested = ros_names(static_cast<AllMessages*>(nullptr));
  EXPECT_EQ(tested, generated);
  EXPECT_EQ(static_cast<int>(tested.size()), kAllMessagesCount);
}

}  // namespace
}  // namespace ros2_messages_test
