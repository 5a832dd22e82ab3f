#include "peer_messages.hpp"

#include <fastdds/rtps/common/SerializedPayload.h>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "fastdds_messagesPubSubTypes.h"

namespace fastdds_peer {

namespace bi = builtin_interfaces::msg::dds_;
namespace gm = geometry_msgs::msg::dds_;
namespace sm = sensor_msgs::msg::dds_;
namespace st = std_msgs::msg::dds_;
namespace tj = trajectory_msgs::msg::dds_;
namespace cic = cartesian_impedance_controller::msg::dds_;
namespace cim = cartesian_impedance_msgs::msg::dds_;

// ---- JSON output --------------------------------------------------------------------------------

std::string json_number(double value) {
  if (std::isnan(value)) {
    return "NaN";
  }
  if (std::isinf(value)) {
    return value > 0 ? "Infinity" : "-Infinity";
  }
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", value);
  return text;
}

std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (byte < 0x20 || byte >= 0x7f) {
      // Non-ASCII bytes too: a fuzzed string need not be UTF-8, the output must stay JSON.
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", byte);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string json_numbers(const std::vector<double>& values) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) {
    out += (i ? "," : "") + json_number(values[i]);
  }
  return out + "]";
}

namespace {

std::string json_strings(const std::vector<std::string>& values) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i) {
    out += (i ? "," : "") + json_string(values[i]);
  }
  return out + "]";
}

/// A JSON object built field by field.
class Object {
 public:
  Object& add(const std::string& key, const std::string& json) {
    body_ += (body_.empty() ? "" : ",") + json_string(key) + ":" + json;
    return *this;
  }
  Object& add(const std::string& key, double value) { return add(key, json_number(value)); }
  std::string str() const { return "{" + body_ + "}"; }

 private:
  std::string body_;
};

std::string json(const bi::Time_& t) {
  return json_number(t.sec() + 1e-9 * t.nanosec());
}
std::string json(const bi::Duration_& t) {
  return json_number(t.sec() + 1e-9 * t.nanosec());
}
std::string json(const gm::Point_& p) {
  return json_numbers({p.x(), p.y(), p.z()});
}
std::string json(const gm::Vector3_& v) {
  return json_numbers({v.x(), v.y(), v.z()});
}
std::string json(const gm::Quaternion_& q) {
  return json_numbers({q.x(), q.y(), q.z(), q.w()});
}
std::string json(const gm::Pose_& p) {
  return Object()
      .add("position", json(p.position()))
      .add("orientation", json(p.orientation()))
      .str();
}
std::string json(const gm::Wrench_& w) {
  return Object().add("force", json(w.force())).add("torque", json(w.torque())).str();
}
Object header(const st::Header_& h) {
  return Object().add("stamp", json(h.stamp())).add("frame_id", json_string(h.frame_id()));
}
std::string json(const gm::PoseStamped_& m) {
  return header(m.header()).add("pose", json(m.pose())).str();
}
std::string json(const gm::WrenchStamped_& m) {
  return header(m.header()).add("wrench", json(m.wrench())).str();
}
std::string json(const sm::JointState_& m) {
  return header(m.header())
      .add("name", json_strings(m.name()))
      .add("position", json_numbers(m.position()))
      .add("velocity", json_numbers(m.velocity()))
      .add("effort", json_numbers(m.effort()))
      .str();
}
std::string json(const st::Float64MultiArray_& m) {
  std::string dims = "[";
  for (const st::MultiArrayDimension_& d : m.layout().dim()) {
    dims += (dims.size() > 1 ? "," : "") + Object()
                                               .add("label", json_string(d.label()))
                                               .add("size", d.size())
                                               .add("stride", d.stride())
                                               .str();
  }
  return Object()
      .add("dim", dims + "]")
      .add("data_offset", m.layout().data_offset())
      .add("data", json_numbers(m.data()))
      .str();
}
std::string json(const cic::ControllerConfig_& m) {
  return Object()
      .add("cartesian_stiffness", json(m.cartesian_stiffness()))
      .add("cartesian_damping_factors", json(m.cartesian_damping_factors()))
      .add("nullspace_stiffness", m.nullspace_stiffness())
      .add("nullspace_damping_factor", m.nullspace_damping_factor())
      .add("q_d_nullspace", json_numbers(m.q_d_nullspace()))
      .str();
}
std::string json(const cic::ControllerState_& m) {
  return header(m.header())
      .add("current_pose", json(m.current_pose()))
      .add("reference_pose", json(m.reference_pose()))
      .add("pose_error", json(m.pose_error()))
      .add("joint_state", json(m.joint_state()))
      .add("commanded_torques", json_numbers(m.commanded_torques()))
      .add("cartesian_stiffness", json(m.cartesian_stiffness()))
      .add("cartesian_damping", json(m.cartesian_damping()))
      .add("nullspace_stiffness", m.nullspace_stiffness())
      .add("nullspace_damping", m.nullspace_damping())
      .add("nullspace_config", json_numbers(m.nullspace_config()))
      .add("commanded_wrench", json(m.commanded_wrench()))
      .add("cartesian_velocity", m.cartesian_velocity())
      .str();
}
std::string json_bool(bool value) {
  return value ? "true" : "false";
}
// This project's full state: the fields the tests look at, not all seventy; of the fields
// appended after the timing (the torque shaping, the hold and the safety layer) every one, the
// last of them the message's last field.
std::string json(const cim::ControllerState_& m) {
  const std::string safety =
      Object()
          .add("reference_speed_limited", json_bool(m.reference_speed_limited()))
          .add("translation_drive_scale", m.translation_drive_scale())
          .add("rotation_drive_scale", m.rotation_drive_scale())
          .add("braking", json_bool(m.braking()))
          .add("force_scale", m.force_scale())
          .add("torque_scale", m.torque_scale())
          .add("reference_clipped", json_bool(m.reference_clipped()))
          .add("workspace_penetration", json(m.workspace_penetration()))
          .add("wall_force", json(m.wall_force()))
          .add("tank_level", m.tank_level())
          .add("tank_draw", m.tank_draw())
          .add("stiffness_change_scale", m.stiffness_change_scale())
          .add("payload_mass", m.payload_mass())
          .add("payload_center_of_mass", json(m.payload_center_of_mass()))
          .add("payload_estimate_valid", json_bool(m.payload_estimate_valid()))
          .add("payload_estimate_mass", m.payload_estimate_mass())
          .add("payload_estimate_center_of_mass", json(m.payload_estimate_center_of_mass()))
          .str();
  return header(m.header())
      .add("status", json_string(m.status()))
      .add("cycle", static_cast<double>(m.cycle()))
      .add("time", m.time())
      .add("current_pose", json(m.current_pose()))
      .add("reference_pose", json(m.reference_pose()))
      .add("cartesian_stiffness", json(m.cartesian_stiffness()))
      .add("commanded_wrench", json(m.commanded_wrench()))
      .add("joint_state", json(m.joint_state()))
      .add("commanded_torques", json_numbers(m.commanded_torques()))
      .add("trajectory_state", json_string(m.trajectory_state()))
      .add("overruns", static_cast<double>(m.overruns()))
      .add("torque_shaping", json_string(m.torque_shaping()))
      .add("torque_shaping_scale", m.torque_shaping_scale())
      .add("holding", json_bool(m.holding()))
      .add("safety", safety)
      .str();
}
std::string json(const tj::JointTrajectory_& m) {
  std::string points = "[";
  for (const tj::JointTrajectoryPoint_& p : m.points()) {
    points +=
        (points.size() > 1 ? "," : "") + Object()
                                             .add("positions", json_numbers(p.positions()))
                                             .add("time_from_start", json(p.time_from_start()))
                                             .str();
  }
  return header(m.header())
      .add("joint_names", json_strings(m.joint_names()))
      .add("points", points + "]")
      .str();
}

// ---- text input ---------------------------------------------------------------------------------

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  if (text.empty()) {
    return parts;
  }
  std::size_t begin = 0;
  for (std::size_t end; (end = text.find(separator, begin)) != std::string::npos; begin = end + 1) {
    parts.push_back(text.substr(begin, end - begin));
  }
  parts.push_back(text.substr(begin));
  return parts;
}

/// Comma-separated numbers (strtod's syntax: nan and inf are allowed, to send them on purpose).
std::vector<double> numbers(const std::string& text, std::size_t expected = 0) {
  std::vector<double> values;
  for (const std::string& part : split(text, ',')) {
    char* end = nullptr;
    values.push_back(std::strtod(part.c_str(), &end));
    if (part.empty() || *end != '\0') {
      throw std::invalid_argument("not a number: " + part);
    }
  }
  if (expected != 0 && values.size() != expected) {
    throw std::invalid_argument("expected " + std::to_string(expected) + " numbers: " + text);
  }
  return values;
}

void set(gm::Vector3_& v, const std::string& text) {
  const auto n = numbers(text, 3);
  v.x(n[0]), v.y(n[1]), v.z(n[2]);
}
void set(gm::Point_& v, const std::string& text) {
  const auto n = numbers(text, 3);
  v.x(n[0]), v.y(n[1]), v.z(n[2]);
}
void set(gm::Quaternion_& q, const std::string& text) {
  const auto n = numbers(text, 4);
  q.x(n[0]), q.y(n[1]), q.z(n[2]), q.w(n[3]);
}
/// Six numbers: force then torque.
void set(gm::Wrench_& w, const std::string& text) {
  const auto n = numbers(text, 6);
  w.force().x(n[0]), w.force().y(n[1]), w.force().z(n[2]);
  w.torque().x(n[3]), w.torque().y(n[4]), w.torque().z(n[5]);
}
void set(bi::Time_& t, double seconds) {
  const double whole = std::floor(seconds);
  t.sec(static_cast<std::int32_t>(whole));
  t.nanosec(static_cast<std::uint32_t>((seconds - whole) * 1e9));
}

bool assign_header(st::Header_& h, const std::string& field, const std::string& value) {
  if (field == "frame_id") {
    h.frame_id(value);
  } else if (field == "stamp") {
    set(h.stamp(), numbers(value, 1)[0]);
  } else {
    return false;
  }
  return true;
}

// Fields per type. Each returns false for a field it does not have.
bool assign(gm::PoseStamped_& m, const std::string& field, const std::string& value) {
  if (field == "position") {
    set(m.pose().position(), value);
  } else if (field == "orientation") {
    set(m.pose().orientation(), value);
  } else {
    return assign_header(m.header(), field, value);
  }
  return true;
}
bool assign(gm::Wrench_& m, const std::string& field, const std::string& value) {
  if (field == "force") {
    set(m.force(), value);
  } else if (field == "torque") {
    set(m.torque(), value);
  } else if (field == "wrench") {
    set(m, value);
  } else {
    return false;
  }
  return true;
}
bool assign(gm::WrenchStamped_& m, const std::string& field, const std::string& value) {
  return assign(m.wrench(), field, value) || assign_header(m.header(), field, value);
}
bool assign(sm::JointState_& m, const std::string& field, const std::string& value) {
  if (field == "name") {
    m.name(split(value, ','));
  } else if (field == "position") {
    m.position(numbers(value));
  } else if (field == "velocity") {
    m.velocity(numbers(value));
  } else if (field == "effort") {
    m.effort(numbers(value));
  } else {
    return assign_header(m.header(), field, value);
  }
  return true;
}
bool assign(st::Float64MultiArray_& m, const std::string& field, const std::string& value) {
  if (field != "data") {
    return false;
  }
  m.data(numbers(value));
  return true;
}
bool assign(cic::ControllerConfig_& m, const std::string& field, const std::string& value) {
  if (field == "stiffness") {
    set(m.cartesian_stiffness(), value);
  } else if (field == "damping") {
    set(m.cartesian_damping_factors(), value);
  } else if (field == "nullspace_stiffness") {
    m.nullspace_stiffness(numbers(value, 1)[0]);
  } else if (field == "nullspace_damping") {
    m.nullspace_damping_factor(numbers(value, 1)[0]);
  } else if (field == "q_d_nullspace") {
    m.q_d_nullspace(numbers(value));
  } else {
    return false;
  }
  return true;
}
/// point=T:p1,p2,... appends a point reaching positions p at T seconds.
bool assign(tj::JointTrajectory_& m, const std::string& field, const std::string& value) {
  if (field == "joint_names") {
    m.joint_names(split(value, ','));
  } else if (field == "point") {
    const auto colon = value.find(':');
    if (colon == std::string::npos) {
      throw std::invalid_argument("point=T:p1,p2,... expected, got " + value);
    }
    tj::JointTrajectoryPoint_ point;
    const double t = numbers(value.substr(0, colon), 1)[0];
    point.time_from_start().sec(static_cast<std::int32_t>(std::floor(t)));
    point.time_from_start().nanosec(static_cast<std::uint32_t>((t - std::floor(t)) * 1e9));
    point.positions(numbers(value.substr(colon + 1)));
    m.points().push_back(point);
  } else {
    return assign_header(m.header(), field, value);
  }
  return true;
}
template <typename T>
bool assign(T&, const std::string&, const std::string&) {
  return false;
}

template <typename T>
auto stamp_header(T& m, double seconds, int) -> decltype(m.header(), void()) {
  set(m.header().stamp(), seconds);
}
template <typename T>
void stamp_header(T&, double, long) {}

template <typename T, typename PubSub>
class Typed final : public Message {
 public:
  explicit Typed(std::string ros_type) : ros_type_(std::move(ros_type)) {}
  const std::string& ros_type() const override { return ros_type_; }
  eprosima::fastdds::dds::TopicDataType* new_type() const override { return new PubSub(); }
  void* data() override { return &sample_; }
  std::string json() const override { return fastdds_peer::json(sample_); }
  void assign(const std::string& field, const std::string& value) override {
    if (!fastdds_peer::assign(sample_, field, value)) {
      throw std::invalid_argument(ros_type_ + " has no settable field " + field);
    }
  }
  void stamp(double seconds) override { stamp_header(sample_, seconds, 0); }

 private:
  std::string ros_type_;
  T sample_;
};

template <typename T, typename PubSub>
std::unique_ptr<Message> typed(const std::string& ros_type) {
  return std::make_unique<Typed<T, PubSub>>(ros_type);
}

}  // namespace

std::unique_ptr<Message> make_message(const std::string& ros_type) {
  using Factory = std::unique_ptr<Message> (*)(const std::string&);
  static const std::pair<const char*, Factory> factories[] = {
      {"geometry_msgs/msg/PoseStamped", typed<gm::PoseStamped_, gm::PoseStamped_PubSubType>},
      {"geometry_msgs/msg/WrenchStamped", typed<gm::WrenchStamped_, gm::WrenchStamped_PubSubType>},
      {"geometry_msgs/msg/Wrench", typed<gm::Wrench_, gm::Wrench_PubSubType>},
      {"sensor_msgs/msg/JointState", typed<sm::JointState_, sm::JointState_PubSubType>},
      {"std_msgs/msg/Float64MultiArray",
       typed<st::Float64MultiArray_, st::Float64MultiArray_PubSubType>},
      {"trajectory_msgs/msg/JointTrajectory",
       typed<tj::JointTrajectory_, tj::JointTrajectory_PubSubType>},
      {"cartesian_impedance_controller/msg/ControllerConfig",
       typed<cic::ControllerConfig_, cic::ControllerConfig_PubSubType>},
      {"cartesian_impedance_controller/msg/ControllerState",
       typed<cic::ControllerState_, cic::ControllerState_PubSubType>},
      {"cartesian_impedance_msgs/msg/ControllerState",
       typed<cim::ControllerState_, cim::ControllerState_PubSubType>},
  };
  for (const auto& [name, factory] : factories) {
    if (ros_type == name) {
      return factory(ros_type);
    }
  }
  throw std::invalid_argument("the peer does not handle " + ros_type);
}

std::vector<unsigned char> serialize(Message& message) {
  std::unique_ptr<eprosima::fastdds::dds::TopicDataType> type(message.new_type());
  eprosima::fastrtps::rtps::SerializedPayload_t payload(
      type->getSerializedSizeProvider(message.data())());
  if (!type->serialize(message.data(), &payload)) {
    throw std::runtime_error("cannot serialize a " + message.ros_type());
  }
  return std::vector<unsigned char>(payload.data, payload.data + payload.length);
}

void assign_all(Message& message, const std::vector<std::string>& assignments) {
  for (const std::string& assignment : assignments) {
    const auto equals = assignment.find('=');
    if (equals == std::string::npos) {
      throw std::invalid_argument("field=value expected, got " + assignment);
    }
    message.assign(assignment.substr(0, equals), assignment.substr(equals + 1));
  }
}

}  // namespace fastdds_peer
