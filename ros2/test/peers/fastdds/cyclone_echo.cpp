// ros2_cyclone_echo: a minimal stand-in for cartesian_impedance_ros2 on Cyclone DDS, so that
// ros2_fastdds_peer can be checked without the node. It takes the node's command line
// (--ros-args -r __ns:=NS -r __node:=NAME, other arguments ignored) and its endpoints' wire
// rules (XCDR1-only readers and writers, typehash USER_DATA, enclave=/;), reads every input
// topic and publishes at 100 Hz a controller_state whose current_pose is the last
// reference_pose received (the start pose, the Panda's ready pose, until then), joint_states
// and commanded_torques. Exits 0 on SIGINT or SIGTERM.

#include <dds/dds.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include "ros2_messages.hpp"

namespace {

using cartesian_impedance_ros2::MessageType;

std::atomic<bool> running{true};

void stop(int) {
  running = false;
}

dds_entity_t check(dds_entity_t entity, const std::string& what) {
  if (entity < 0) {
    std::fprintf(stderr, "ros2_cyclone_echo: %s: %s\n", what.c_str(), dds_strretcode(entity));
    std::exit(1);
  }
  return entity;
}

template <typename Message>
dds_entity_t endpoint(dds_entity_t participant, const std::string& ros_topic, bool writer) {
  const dds_entity_t topic = check(dds_create_topic(participant, MessageType<Message>::descriptor(),
                                                    ("rt" + ros_topic).c_str(), nullptr, nullptr),
                                   "topic " + ros_topic);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  const std::string user_data = std::string("typehash=") + MessageType<Message>::type_hash + ";";
  dds_qset_userdata(qos, user_data.data(), user_data.size());
  const dds_entity_t entity = writer ? dds_create_writer(participant, topic, qos, nullptr)
                                     : dds_create_reader(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  return check(entity, "endpoint on " + ros_topic);
}

/// Takes every sample waiting in `reader`; copies the pose of the last valid one to `last` if
/// given.
long drain(dds_entity_t reader, geometry_msgs_msg_dds__Pose_* last = nullptr) {
  long count = 0;
  void* samples[16] = {};
  dds_sample_info_t infos[16];
  int n;
  while ((n = dds_take(reader, samples, infos, 16, 16)) > 0) {
    for (int i = 0; i < n; ++i) {
      if (infos[i].valid_data) {
        ++count;
        if (last != nullptr) {
          *last = static_cast<const geometry_msgs_msg_dds__PoseStamped_*>(samples[i])->pose;
        }
      }
    }
    dds_return_loan(reader, samples, n);
  }
  return count;
}

std::string argument_value(int argc, char** argv, const std::string& key, std::string fallback) {
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], "-r") == 0 && std::string(argv[i + 1]).rfind(key + ":=", 0) == 0) {
      fallback = std::string(argv[i + 1]).substr(key.size() + 2);
    }
  }
  return fallback;
}

}  // namespace

int main(int argc, char** argv) {
  std::string ns = argument_value(argc, argv, "__ns", "/");
  const std::string node = argument_value(argc, argv, "__node", "cartesian_impedance_controller");
  if (ns.size() > 1 && ns.back() == '/') {
    ns.pop_back();
  }
  const std::string base = ns == "/" ? "" : ns;
  const std::string fq = base + "/" + node;
  const char* domain_text = std::getenv("ROS_DOMAIN_ID");
  const auto domain = static_cast<dds_domainid_t>(domain_text ? std::atoi(domain_text) : 0);

  std::signal(SIGINT, stop);
  std::signal(SIGTERM, stop);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_userdata(qos, "enclave=/;", 10);
  const dds_entity_t participant =
      check(dds_create_participant(domain, qos, nullptr), "participant");
  dds_delete_qos(qos);

  const dds_entity_t reference =
      endpoint<geometry_msgs_msg_dds__PoseStamped_>(participant, fq + "/reference_pose", false);
  const dds_entity_t inputs[] = {
      endpoint<geometry_msgs_msg_dds__WrenchStamped_>(participant, fq + "/set_cartesian_stiffness",
                                                      false),
      endpoint<geometry_msgs_msg_dds__WrenchStamped_>(participant, fq + "/set_cartesian_wrench",
                                                      false),
      endpoint<geometry_msgs_msg_dds__Wrench_>(participant, fq + "/set_damping_factors", false),
      endpoint<cartesian_impedance_controller_msg_dds__ControllerConfig_>(
          participant, fq + "/set_config", false),
      endpoint<trajectory_msgs_msg_dds__JointTrajectory_>(participant, base + "/joint_trajectory",
                                                          false),
  };
  const dds_entity_t state_writer =
      endpoint<cartesian_impedance_controller_msg_dds__ControllerState_>(
          participant, fq + "/controller_state", true);
  const dds_entity_t joints_writer =
      endpoint<sensor_msgs_msg_dds__JointState_>(participant, base + "/joint_states", true);
  const dds_entity_t torques_writer =
      endpoint<std_msgs_msg_dds__Float64MultiArray_>(participant, fq + "/commanded_torques", true);

  geometry_msgs_msg_dds__Pose_ last{};
  last.position = {0.307, 0.0, 0.590};
  last.orientation = {1.0, 0.0, 0.0, 0.0};
  char* names[7] = {const_cast<char*>("panda_joint1"), const_cast<char*>("panda_joint2"),
                    const_cast<char*>("panda_joint3"), const_cast<char*>("panda_joint4"),
                    const_cast<char*>("panda_joint5"), const_cast<char*>("panda_joint6"),
                    const_cast<char*>("panda_joint7")};
  double zeros[7] = {};
  char empty[] = "";
  long poses = 0;
  long others = 0;
  auto next = std::chrono::steady_clock::now();
  while (running) {
    poses += drain(reference, &last);
    for (const dds_entity_t input : inputs) {
      others += drain(input);
    }
    const dds_time_t now = dds_time();
    builtin_interfaces_msg_dds__Time_ stamp{static_cast<int32_t>(now / DDS_NSECS_IN_SEC),
                                            static_cast<uint32_t>(now % DDS_NSECS_IN_SEC)};
    sensor_msgs_msg_dds__JointState_ joints{};
    joints.header = {stamp, empty};
    joints.name = {7, 7, names, false};
    joints.position = joints.velocity = joints.effort = {7, 7, zeros, false};
    cartesian_impedance_controller_msg_dds__ControllerState_ state{};
    state.header = {stamp, empty};
    state.current_pose = state.reference_pose = last;
    state.pose_error.orientation.w = 1.0;
    state.joint_state = joints;
    state.commanded_torques = {7, 7, zeros, false};
    std_msgs_msg_dds__Float64MultiArray_ torques{};
    torques.data = {7, 7, zeros, false};
    dds_write(state_writer, &state);
    dds_write(joints_writer, &joints);
    dds_write(torques_writer, &torques);
    next += std::chrono::milliseconds(10);
    std::this_thread::sleep_until(next);
  }
  std::printf("{\"event\":\"exit\",\"reference_poses\":%ld,\"other_inputs\":%ld}\n", poses, others);
  dds_delete(participant);
  return 0;
}
