// ros2_fastdds_service_probe: what a ROS 2 client on Fast DDS (rmw_fastrtps) gets from the
// node's list_parameters service. rmw_fastrtps frames a request differently from
// rmw_cyclonedds_cpp: the payload is the request's fields alone, and the request's identity is
// the RTPS sample identity of the write (writer GUID + sequence number); a reply is accepted only
// if its related_sample_identity names the client's request writer (or reply reader). The probe
// writes such a request (raw bytes under ROS 2's type name) and, to compare, one framed as
// rmw_cyclonedds_cpp frames it, and reports every reply with its related_sample_identity. One
// JSON object per line; exit 0 if it ran (whatever it saw), 1 if the endpoints did not match.
//
//   ros2_fastdds_service_probe NODE [--timeout S]
//
// Environment: ROS_DOMAIN_ID, FASTRTPS_DEFAULT_PROFILES_FILE (as ros2_fastdds_peer).

#include <fastdds/rtps/common/WriteParams.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <thread>

#include "peer_fuzz.hpp"

namespace fdds = eprosima::fastdds::dds;
namespace frtps = eprosima::fastrtps::rtps;
using fastdds_peer::Bytes;
using fastdds_peer::RawType;

namespace {

std::string guid_text(const frtps::GUID_t& guid) {
  std::ostringstream out;
  out << guid;
  return out.str();
}

std::string identity_text(const frtps::SampleIdentity& id) {
  return "{\"writer\":\"" + guid_text(id.writer_guid()) +
         "\",\"sequence\":" + std::to_string(id.sequence_number().to64long()) + "}";
}

// list_parameters' request fields (prefixes: none, depth: 0), XCDR1 little-endian with its
// encapsulation header; with rmw_cyclonedds_cpp's header (client id, sequence number) in front
// if `client` is not 0.
Bytes list_request(std::uint64_t client, std::int64_t sequence) {
  Bytes b = {0x00, 0x01, 0x00, 0x00};
  const auto u64 = [&](std::uint64_t v) {
    for (int i = 0; i < 8; ++i) b.push_back(static_cast<unsigned char>(v >> (8 * i)));
  };
  if (client != 0) {
    u64(client);
    u64(static_cast<std::uint64_t>(sequence));
  }
  for (int i = 0; i < 4; ++i) b.push_back(0);  // prefixes: 0 elements
  for (int i = 0; i < 4; ++i) b.push_back(0);  // padding to 8
  u64(0);                                      // depth
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: ros2_fastdds_service_probe NODE [--timeout S]\n");
    return 2;
  }
  const std::string node = argv[1];
  const double timeout = argc > 3 ? std::atof(argv[3]) : 3.0;
  const char* domain_text = std::getenv("ROS_DOMAIN_ID");
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  factory->load_profiles();
  fdds::DomainParticipant* participant = factory->create_participant(
      domain_text ? std::atoi(domain_text) : 0, factory->get_default_participant_qos());
  if (participant == nullptr) return 1;
  auto* request_type = new RawType("rcl_interfaces::srv::dds_::ListParameters_Request_");
  auto* reply_type = new RawType("rcl_interfaces::srv::dds_::ListParameters_Response_");
  for (RawType* type : {request_type, reply_type}) {
    type->auto_fill_type_information(false);
    type->auto_fill_type_object(false);
    fdds::TypeSupport(type).register_type(participant);
  }
  fdds::Topic* request_topic = participant->create_topic(
      "rq" + node + "/list_parametersRequest", request_type->getName(), fdds::TOPIC_QOS_DEFAULT);
  fdds::Topic* reply_topic = participant->create_topic(
      "rr" + node + "/list_parametersReply", reply_type->getName(), fdds::TOPIC_QOS_DEFAULT);
  fdds::Publisher* publisher = participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  fdds::Subscriber* subscriber = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  // rmw_fastrtps's service QoS: reliable, volatile, keep last 10, XCDR1.
  fdds::DataWriterQos wqos = publisher->get_default_datawriter_qos();
  wqos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  wqos.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
  wqos.history().depth = 10;
  wqos.representation().m_value = {fdds::XCDR_DATA_REPRESENTATION};
  wqos.endpoint().history_memory_policy = frtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
  fdds::DataReaderQos rqos = subscriber->get_default_datareader_qos();
  rqos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  rqos.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
  rqos.history().depth = 10;
  rqos.type_consistency().representation.m_value = {fdds::XCDR_DATA_REPRESENTATION};
  rqos.endpoint().history_memory_policy = frtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
  fdds::DataWriter* writer = publisher->create_datawriter(request_topic, wqos);
  fdds::DataReader* reader = subscriber->create_datareader(reply_topic, rqos);
  if (writer == nullptr || reader == nullptr) return 1;

  const auto until = [](double seconds) {
    return std::chrono::steady_clock::now() +
           std::chrono::duration_cast<std::chrono::steady_clock::duration>(
               std::chrono::duration<double>(seconds));
  };
  for (auto end = until(10.0); std::chrono::steady_clock::now() < end;) {
    fdds::PublicationMatchedStatus pub;
    fdds::SubscriptionMatchedStatus sub;
    writer->get_publication_matched_status(pub);
    reader->get_subscription_matched_status(sub);
    if (pub.current_count > 0 && sub.current_count > 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  fdds::PublicationMatchedStatus pub;
  fdds::SubscriptionMatchedStatus sub;
  writer->get_publication_matched_status(pub);
  reader->get_subscription_matched_status(sub);
  std::printf("{\"event\":\"matched\",\"request_readers\":%d,\"reply_writers\":%d}\n",
              pub.current_count, sub.current_count);
  if (pub.current_count == 0 || sub.current_count == 0) return 1;

  const auto ask = [&](const char* framing, Bytes request) {
    frtps::WriteParams params;
    writer->write(&request, params);
    std::printf("{\"event\":\"request\",\"framing\":\"%s\",\"bytes\":%zu,\"identity\":%s}\n",
                framing, request.size() - 4, identity_text(params.sample_identity()).c_str());
    int replies = 0;
    for (auto end = until(timeout); std::chrono::steady_clock::now() < end;) {
      Bytes reply;
      fdds::SampleInfo info;
      if (reader->take_next_sample(&reply, &info) == ReturnCode_t::RETCODE_OK && info.valid_data) {
        ++replies;
        const bool for_this_request =
            info.related_sample_identity.writer_guid() == params.sample_identity().writer_guid();
        std::printf(
            "{\"event\":\"reply\",\"framing\":\"%s\",\"bytes\":%zu,\"related_sample_identity\":%s,"
            "\"accepted_by_rmw_fastrtps\":%s}\n",
            framing, reply.size() - 4, identity_text(info.related_sample_identity).c_str(),
            for_this_request ? "true" : "false");
        continue;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    std::printf("{\"event\":\"done\",\"framing\":\"%s\",\"replies\":%d}\n", framing, replies);
    std::fflush(stdout);
  };
  ask("rmw_fastrtps", list_request(0, 0));
  ask("rmw_cyclonedds_cpp", list_request(0x1122334455667788ull, 1));
  participant->delete_contained_entities();
  factory->delete_participant(participant);
  return 0;
}
