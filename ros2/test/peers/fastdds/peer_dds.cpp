#include "peer_dds.hpp"

#include <chrono>
#include <cstdlib>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <stdexcept>
#include <thread>

namespace fastdds_peer {

namespace dds = eprosima::fastdds::dds;

const TypeNames& type_names(const std::string& ros_type) {
  for (const TypeNames& names : kTypeNames) {
    if (ros_type == names.ros_name) {
      return names;
    }
  }
  throw std::invalid_argument("unknown message type " + ros_type);
}

std::string dds_topic(const std::string& ros_topic) {
  if (ros_topic.empty() || ros_topic.front() != '/') {
    throw std::invalid_argument("topic " + ros_topic + " is not fully qualified");
  }
  return "rt" + ros_topic;
}

double wall_time() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

namespace {

std::uint32_t domain_from_environment() {
  const char* text = std::getenv("ROS_DOMAIN_ID");
  if (text == nullptr || *text == '\0') {
    return 0;
  }
  char* end = nullptr;
  const long id = std::strtol(text, &end, 10);
  // 232 is the largest domain whose RTPS ports fit in 16 bits, the limit ROS 2 documents.
  if (*end != '\0' || id < 0 || id > 232) {
    throw std::runtime_error(std::string("invalid ROS_DOMAIN_ID ") + text);
  }
  return static_cast<std::uint32_t>(id);
}

std::vector<unsigned char> octets(const std::string& text) {
  return std::vector<unsigned char>(text.begin(), text.end());
}

}  // namespace

Peer::Peer() : domain_(domain_from_environment()) {
  auto* factory = dds::DomainParticipantFactory::get_instance();
  // Reads FASTRTPS_DEFAULT_PROFILES_FILE (or ./DEFAULT_FASTRTPS_PROFILES.xml), whose default
  // participant profile then becomes PARTICIPANT_QOS_DEFAULT.
  factory->load_profiles();
  dds::DomainParticipantQos qos = factory->get_default_participant_qos();
  qos.name("ros2_fastdds_peer");
  qos.user_data().data_vec(octets("enclave=/;"));
  participant_ = factory->create_participant(domain_, qos);
  if (participant_ == nullptr) {
    throw std::runtime_error("Fast DDS could not create a participant in domain " +
                             std::to_string(domain_));
  }
  publisher_ = participant_->create_publisher(dds::PUBLISHER_QOS_DEFAULT);
  subscriber_ = participant_->create_subscriber(dds::SUBSCRIBER_QOS_DEFAULT);
  if (publisher_ == nullptr || subscriber_ == nullptr) {
    throw std::runtime_error("Fast DDS could not create a publisher or subscriber");
  }
}

Peer::~Peer() {
  participant_->delete_contained_entities();
  dds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

dds::Topic* Peer::topic(const std::string& ros_topic, dds::TopicDataType* type) {
  // rmw_fastrtps sends no XTypes type information either: matching is by type name alone.
  type->auto_fill_type_information(false);
  type->auto_fill_type_object(false);
  const std::string type_name = type->getName();
  // The peer registers each type name once; a second class under the same name would make the
  // participant serialize with whichever came first.
  if (!participant_->find_type(type_name).empty()) {
    delete type;
    throw std::runtime_error("type " + type_name + " is registered already");
  }
  dds::TypeSupport support(type);
  if (support.register_type(participant_) != dds::TypeSupport::ReturnCode_t::RETCODE_OK) {
    throw std::runtime_error("cannot register type " + type_name);
  }
  const std::string name = dds_topic(ros_topic);
  const auto found = topics_.find(name);
  if (found != topics_.end()) {
    if (found->second->get_type_name() != type_name) {
      throw std::runtime_error("topic " + name + " already has type " +
                               found->second->get_type_name());
    }
    return found->second;
  }
  dds::Topic* created = participant_->create_topic(name, type_name, dds::TOPIC_QOS_DEFAULT);
  if (created == nullptr) {
    throw std::runtime_error("cannot create topic " + name);
  }
  topics_.emplace(name, created);
  return created;
}

dds::DataWriter* Peer::writer(const std::string& ros_topic, dds::TopicDataType* type,
                              const std::string& type_hash, Representation representation) {
  dds::Topic* t = topic(ros_topic, type);
  dds::DataWriterQos qos = publisher_->get_default_datawriter_qos();
  qos.reliability().kind = dds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = dds::VOLATILE_DURABILITY_QOS;
  qos.history().kind = dds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = 10;
  // Fast DDS 2.9 offers nothing explicit by default; ROS 2 pins XCDR1.
  qos.representation().m_value = {representation == Representation::xcdr1
                                      ? dds::XCDR_DATA_REPRESENTATION
                                      : dds::XCDR2_DATA_REPRESENTATION};
  // Unbounded strings and sequences: payloads grow past the generated "maximum" size.
  qos.endpoint().history_memory_policy =
      eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
  // Readers acknowledge when a heartbeat asks; Fast DDS's default period (3 s) would make every
  // wait for acknowledgement, and so every short-lived publisher, take seconds.
  qos.reliable_writer_qos().times.heartbeatPeriod = eprosima::fastrtps::Duration_t(0, 100000000);
  qos.user_data().data_vec(octets("typehash=" + type_hash + ";"));
  dds::DataWriter* w = publisher_->create_datawriter(t, qos);
  if (w == nullptr) {
    throw std::runtime_error("cannot create a writer on " + ros_topic);
  }
  return w;
}

dds::DataReader* Peer::reader(const std::string& ros_topic, dds::TopicDataType* type,
                              const std::string& type_hash) {
  dds::Topic* t = topic(ros_topic, type);
  dds::DataReaderQos qos = subscriber_->get_default_datareader_qos();
  qos.reliability().kind = dds::RELIABLE_RELIABILITY_QOS;
  qos.durability().kind = dds::VOLATILE_DURABILITY_QOS;
  qos.history().kind = dds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = 10;
  qos.type_consistency().representation.m_value = {dds::XCDR_DATA_REPRESENTATION};
  qos.endpoint().history_memory_policy =
      eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
  qos.user_data().data_vec(octets("typehash=" + type_hash + ";"));
  dds::DataReader* r = subscriber_->create_datareader(t, qos);
  if (r == nullptr) {
    throw std::runtime_error("cannot create a reader on " + ros_topic);
  }
  return r;
}

int matched(dds::DataWriter* writer) {
  dds::PublicationMatchedStatus status;
  writer->get_publication_matched_status(status);
  return status.current_count;
}

int matched(dds::DataReader* reader) {
  dds::SubscriptionMatchedStatus status;
  reader->get_subscription_matched_status(status);
  return status.current_count;
}

int wait_matched(dds::DataWriter* writer, double timeout) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  while (matched(writer) == 0 && std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return matched(writer);
}

}  // namespace fastdds_peer
