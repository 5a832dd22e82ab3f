// ros2_cyclone_pose_writer xcdr1|xcdr2 TOPIC X Y Z QX QY QZ QW [SECONDS]: a PoseStamped writer
// on Cyclone DDS that offers one data representation and announces it in discovery. Fast DDS 2.9
// cannot announce one: its DataWriter keeps the DataRepresentation QoS to itself (the SEDP
// parameter is commented out in 2.x), so a Fast DDS "XCDR2" writer looks like an XCDR1 one to
// every reader; the XCDR2 test needs this writer instead, and xcdr1 is its control. Everything
// else follows ROS 2's rules. Publishes every 100 ms for SECONDS (default 3), prints the match
// count as JSON and exits 0 (the caller judges).

#include <dds/dds.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "ros2_messages.hpp"

int main(int argc, char** argv) {
  using Pose = geometry_msgs_msg_dds__PoseStamped_;
  using Type = cartesian_impedance_ros2::MessageType<Pose>;
  const std::string representation = argc > 1 ? argv[1] : "";
  if (argc < 10 || (representation != "xcdr1" && representation != "xcdr2")) {
    std::fprintf(stderr, "usage: %s xcdr1|xcdr2 TOPIC X Y Z QX QY QZ QW [SECONDS]\n", argv[0]);
    return 2;
  }
  double v[7];
  for (int i = 0; i < 7; ++i) {
    v[i] = std::strtod(argv[3 + i], nullptr);
  }
  const double seconds = argc > 10 ? std::strtod(argv[10], nullptr) : 3.0;
  const char* domain_text = std::getenv("ROS_DOMAIN_ID");
  const auto domain = static_cast<dds_domainid_t>(domain_text ? std::atoi(domain_text) : 0);

  dds_qos_t* qos = dds_create_qos();
  dds_qset_userdata(qos, "enclave=/;", 10);
  const dds_entity_t participant = dds_create_participant(domain, qos, nullptr);
  dds_delete_qos(qos);
  const dds_entity_t topic = dds_create_topic(
      participant, Type::descriptor(), (std::string("rt") + argv[2]).c_str(), nullptr, nullptr);
  qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
  const dds_data_representation_id_t id =
      representation == "xcdr1" ? DDS_DATA_REPRESENTATION_XCDR1 : DDS_DATA_REPRESENTATION_XCDR2;
  dds_qset_data_representation(qos, 1, &id);
  const std::string user_data = std::string("typehash=") + Type::type_hash + ";";
  dds_qset_userdata(qos, user_data.data(), user_data.size());
  const dds_entity_t writer = dds_create_writer(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  if (participant < 0 || topic < 0 || writer < 0) {
    std::fprintf(stderr, "ros2_cyclone_pose_writer: cannot create the writer\n");
    return 1;
  }

  Pose pose{};
  char frame_id[] = "";
  pose.header.frame_id = frame_id;
  pose.pose.position = {v[0], v[1], v[2]};
  pose.pose.orientation = {v[3], v[4], v[5], v[6]};
  const auto end = std::chrono::steady_clock::now() +
                   std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                       std::chrono::duration<double>(seconds));
  int written = 0;
  dds_publication_matched_status_t matched{};
  while (std::chrono::steady_clock::now() < end) {
    const dds_time_t now = dds_time();
    pose.header.stamp = {static_cast<int32_t>(now / DDS_NSECS_IN_SEC),
                         static_cast<uint32_t>(now % DDS_NSECS_IN_SEC)};
    written += dds_write(writer, &pose) == DDS_RETCODE_OK ? 1 : 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  dds_get_publication_matched_status(writer, &matched);
  std::printf("{\"event\":\"result\",\"matched\":%u,\"total_matched\":%u,\"written\":%d}\n",
              matched.current_count, matched.total_count, written);
  dds_delete(participant);
  return 0;
}
