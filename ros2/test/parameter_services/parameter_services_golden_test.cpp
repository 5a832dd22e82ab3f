// Golden bytes of the parameter services on the wire, as rmw_cyclonedds_cpp writes them: the
// request header (client id: uint64, sequence number: int64) in the same CDR stream as the fields,
// then the fields of the .srv file. Cyclone's serializer of the node's generated types must write
// exactly what the hand encoder (cdr_writer.hpp) writes, and read it back.

#include <gtest/gtest.h>

#include <iomanip>
#include <sstream>

#include "cdr_writer.hpp"
#include "cyclone_codec.hpp"
#include "ros2_messages.hpp"

namespace parameter_services_test {
namespace {

using ros2_messages_test::CdrWriter;
using ros2_messages_test::hex;

constexpr std::uint64_t kClient = 0x0102030405060708ull;
constexpr std::int64_t kSequence = 42;

// A ParameterValue of the hand encoder: type and the one member it names, the rest empty.
void value(CdrWriter& w, std::uint8_t type, double number, const std::string& text,
           const std::vector<double>& numbers) {
  w.octet(type);
  w.boolean(false);
  w.int64(0);
  w.float64(type == 3 ? number : 0.0);
  w.string(text);
  w.sequence_length(0);  // byte_array_value
  w.sequence_length(0);  // bool_array_value
  w.sequence_length(0);  // integer_array_value
  w.sequence_length(static_cast<uint32_t>(numbers.size()));
  for (double x : numbers) w.float64(x);
  w.sequence_length(0);  // string_array_value
}

// set_parameters: [stiffness.translation = [500, 600, 700], stiffness_frame = "base"].
TEST(ParameterServicesGolden, SetParametersRequestIsHeaderThenFields) {
  CdrWriter w;
  w.uint64(kClient);
  w.int64(kSequence);
  w.sequence_length(2);
  w.string("stiffness.translation");
  value(w, 8, 0.0, "", {500, 600, 700});
  w.string("stiffness_frame");
  value(w, 4, 0.0, "base", {});
  const std::vector<uint8_t> golden = w.bytes();
  // The header is the first 16 bytes of the payload, little-endian.
  ASSERT_GT(golden.size(), 20u);
  EXPECT_EQ(golden[4], 0x08);
  EXPECT_EQ(golden[11], 0x01);
  EXPECT_EQ(golden[12], 42);

  std::vector<double> numbers = {500, 600, 700};
  rcl_interfaces_msg_dds__Parameter_ parameters[2] = {};
  parameters[0].name = const_cast<char*>("stiffness.translation");
  parameters[0].value.type = 8;
  parameters[0].value.string_value = const_cast<char*>("");
  parameters[0].value.double_array_value._buffer = numbers.data();
  parameters[0].value.double_array_value._length = parameters[0].value.double_array_value._maximum =
      3;
  parameters[1].name = const_cast<char*>("stiffness_frame");
  parameters[1].value.type = 4;
  parameters[1].value.string_value = const_cast<char*>("base");
  rcl_interfaces_srv_dds__SetParameters_Request_ request{};
  request.cdds_request_header_guid = kClient;
  request.cdds_request_header_seq = kSequence;
  request.parameters._buffer = parameters;
  request.parameters._length = request.parameters._maximum = 2;

  using Type =
      cartesian_impedance_ros2::MessageType<rcl_interfaces_srv_dds__SetParameters_Request_>;
  const ddsi_sertype* type = ros2_messages_test::sertype_of(Type::descriptor());
  ASSERT_NE(type, nullptr);
  EXPECT_EQ(hex(ros2_messages_test::cyclone_serialize(type, &request)), hex(golden));
  EXPECT_STREQ(Type::descriptor()->m_typename, "rcl_interfaces::srv::dds_::SetParameters_Request_");

  rcl_interfaces_srv_dds__SetParameters_Request_ decoded{};
  ASSERT_TRUE(ros2_messages_test::cyclone_deserialize(type, golden, &decoded));
  EXPECT_EQ(decoded.cdds_request_header_guid, kClient);
  EXPECT_EQ(decoded.cdds_request_header_seq, kSequence);
  ASSERT_EQ(decoded.parameters._length, 2u);
  EXPECT_STREQ(decoded.parameters._buffer[1].value.string_value, "base");
  EXPECT_EQ(decoded.parameters._buffer[0].value.double_array_value._buffer[2], 700.0);
  dds_sample_free(&decoded, Type::descriptor(), DDS_FREE_CONTENTS);
}

// describe_parameters' reply: one descriptor with a floating-point range and no integer range.
TEST(ParameterServicesGolden, DescribeParametersReplyIsHeaderThenFields) {
  CdrWriter w;
  w.uint64(kClient);
  w.int64(kSequence);
  w.sequence_length(1);
  w.string("stiffness.translation");
  w.octet(8);
  w.string("stiffness [N/m]");
  w.string("each value in [0, 5000] N/m");
  w.boolean(false);  // read_only
  w.boolean(false);  // dynamic_typing
  w.sequence_length(1);
  w.float64(0.0);
  w.float64(5000.0);
  w.float64(0.0);
  w.sequence_length(0);
  const std::vector<uint8_t> golden = w.bytes();

  rcl_interfaces_msg_dds__FloatingPointRange_ range{0.0, 5000.0, 0.0};
  rcl_interfaces_msg_dds__ParameterDescriptor_ descriptor{};
  descriptor.name = const_cast<char*>("stiffness.translation");
  descriptor.type = 8;
  descriptor.description = const_cast<char*>("stiffness [N/m]");
  descriptor.additional_constraints = const_cast<char*>("each value in [0, 5000] N/m");
  descriptor.floating_point_range._buffer = &range;
  descriptor.floating_point_range._length = descriptor.floating_point_range._maximum = 1;
  rcl_interfaces_srv_dds__DescribeParameters_Response_ reply{};
  reply.cdds_request_header_guid = kClient;
  reply.cdds_request_header_seq = kSequence;
  reply.descriptors._buffer = &descriptor;
  reply.descriptors._length = reply.descriptors._maximum = 1;

  using Type =
      cartesian_impedance_ros2::MessageType<rcl_interfaces_srv_dds__DescribeParameters_Response_>;
  const ddsi_sertype* type = ros2_messages_test::sertype_of(Type::descriptor());
  ASSERT_NE(type, nullptr);
  EXPECT_EQ(hex(ros2_messages_test::cyclone_serialize(type, &reply)), hex(golden));
  EXPECT_STREQ(Type::descriptor()->m_typename,
               "rcl_interfaces::srv::dds_::DescribeParameters_Response_");

  rcl_interfaces_srv_dds__DescribeParameters_Response_ decoded{};
  ASSERT_TRUE(ros2_messages_test::cyclone_deserialize(type, golden, &decoded));
  EXPECT_EQ(decoded.cdds_request_header_guid, kClient);
  EXPECT_EQ(decoded.cdds_request_header_seq, kSequence);
  ASSERT_EQ(decoded.descriptors._length, 1u);
  ASSERT_EQ(decoded.descriptors._buffer[0].floating_point_range._length, 1u);
  EXPECT_EQ(decoded.descriptors._buffer[0].floating_point_range._buffer[0].to_value, 5000.0);
  dds_sample_free(&decoded, Type::descriptor(), DDS_FREE_CONTENTS);
}

}  // namespace
}  // namespace parameter_services_test
