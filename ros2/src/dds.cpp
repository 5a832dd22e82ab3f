#include "dds.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <cartesian_impedance/core/error.hpp>

namespace cartesian_impedance_ros2 {

namespace ci = cartesian_impedance;

Entity::~Entity() {
  if (id_ > 0) dds_delete(id_);
}

Entity& Entity::operator=(Entity&& other) noexcept {
  if (this != &other) {
    if (id_ > 0) dds_delete(id_);
    id_ = other.id_;
    other.id_ = 0;
  }
  return *this;
}

dds_entity_t check(dds_entity_t result, const std::string& what) {
  if (result < 0) {
    throw ci::Error("DDS: cannot create the " + what + ": " + dds_strretcode(result));
  }
  return result;
}

namespace {

std::uint32_t domain_from_environment() {
  const char* text = std::getenv("ROS_DOMAIN_ID");
  if (text == nullptr || *text == '\0') return 0;
  char* end = nullptr;
  errno = 0;
  const unsigned long value = std::strtoul(text, &end, 10);
  // ROS 2 accepts 0..232 (the ports of higher domains overflow RTPS's port formula with the
  // default participant range); Cyclone itself would take more.
  if (errno != 0 || *end != '\0' || text[0] == '-' || value > 232) {
    throw ci::Error(std::string("ROS_DOMAIN_ID = '") + text +
                    "' is not a domain id (a whole number in [0, 232])");
  }
  return static_cast<std::uint32_t>(value);
}

}  // namespace

Participant::Participant() : domain_(domain_from_environment()) {
  dds_qos_t* qos = dds_create_qos();
  // What ROS 2 participants announce: the security enclave, which `ros2 node list` and the
  // graph of Iron and later read.
  static const char kEnclave[] = "enclave=/;";
  dds_qset_userdata(qos, kEnclave, sizeof kEnclave - 1);
  const dds_entity_t participant = dds_create_participant(domain_, qos, nullptr);
  dds_delete_qos(qos);
  participant_ = Entity(check(participant, "participant in domain " + std::to_string(domain_)));
}

dds_qos_t* endpoint_qos(const TopicQos& topic, const char* type_hash) {
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, topic.reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                       DDS_MSECS(100));
  dds_qset_durability(
      qos, topic.transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, topic.depth);
  // XCDR1 only, as ROS 2's layers: a reader that also accepted XCDR2 would match writers that ROS 2
  // nodes cannot read, and a writer would be free to choose XCDR2.
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  if (type_hash != nullptr) {
    const std::string user_data = std::string("typehash=") + type_hash + ";";
    dds_qset_userdata(qos, user_data.data(), user_data.size());
  }
  return qos;
}

dds_entity_t find_or_create_topic(const Participant& participant,
                                  const dds_topic_descriptor_t* type, const std::string& dds_name) {
  dds_qos_t* qos = dds_create_qos();
  const dds_entity_t topic =
      dds_create_topic(participant.get(), type, dds_name.c_str(), qos, nullptr);
  dds_delete_qos(qos);
  return check(topic, "topic " + dds_name + " (" + type->m_typename + ")");
}

int matched_readers(dds_entity_t writer) {
  dds_publication_matched_status_t status{};
  if (dds_get_publication_matched_status(writer, &status) < 0) return 0;
  return static_cast<int>(status.current_count);
}

}  // namespace cartesian_impedance_ros2
