#pragma once
// The independent client of ROS 2's parameter services: Cyclone DDS's C API and the test's own
// types (peer_types.idl), framing rmw_cyclonedds_cpp's request header itself. It knows the wire
// description only (topics rq<node>/<service>Request and rr<node>/<service>Reply, the DDS type
// names, the header, the QoS), none of the node's code.

#include <dds/dds.h>

#include <chrono>
#include <cstdlib>
#include <deque>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "peer_types.h"

namespace parameter_services_test {

using Clock = std::chrono::steady_clock;

// ROS 2's DDS type names of a service's request and reply.
inline std::string request_type(const std::string& service) {
  return "rcl_interfaces::srv::dds_::" + service + "_Request_";
}
inline std::string reply_type(const std::string& service) {
  return "rcl_interfaces::srv::dds_::" + service + "_Response_";
}

// C sequences pointing at test-owned storage.
template <typename Sequence, typename T>
void point(Sequence& sequence, T* data, std::size_t size) {
  sequence._maximum = sequence._length = static_cast<std::uint32_t>(size);
  sequence._buffer = size == 0 ? nullptr : data;
  sequence._release = false;
}

class Peer {
 public:
  // `client_id`: the 64-bit id the header carries; the node must echo it.
  explicit Peer(std::uint64_t client_id) : client_id_(client_id) {
    const char* domain = std::getenv("ROS_DOMAIN_ID");
    participant_ = dds_create_participant(
        domain ? static_cast<dds_domainid_t>(std::atoi(domain)) : 0, nullptr, nullptr);
    if (participant_ < 0) throw std::runtime_error("peer: no participant");
  }
  ~Peer() { dds_delete(participant_); }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;

  std::uint64_t client_id() const { return client_id_; }
  dds_entity_t participant() const { return participant_; }

  // A descriptor of the test's types under ROS 2's type name.
  const dds_topic_descriptor_t* named(const dds_topic_descriptor_t& type, const std::string& name) {
    names_.push_back(name);
    descriptors_.push_back(type);
    descriptors_.back().m_typename = names_.back().c_str();
    return &descriptors_.back();
  }

  // QoS of ROS 2's services (reliable, volatile, keep last 10), XCDR1, and the client's id in
  // USER_DATA as rmw_cyclonedds_cpp's clients announce it.
  dds_qos_t* service_qos() const {
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
    const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
    dds_qset_data_representation(qos, 1, &xcdr1);
    const std::string user_data = "clientid=" + std::to_string(client_id_) + ";";
    dds_qset_userdata(qos, user_data.data(), user_data.size());
    return qos;
  }

  struct Endpoints {
    dds_entity_t writer = 0;
    dds_entity_t reader = 0;
  };

  // The request writer and reply reader of `node`/`service_name` (e.g. "get_parameters").
  Endpoints service(const std::string& node, const std::string& service_name,
                    const dds_topic_descriptor_t* request, const dds_topic_descriptor_t* reply) {
    dds_qos_t* qos = service_qos();
    const std::string base = node + "/" + service_name;
    Endpoints e;
    e.writer =
        dds_create_writer(participant_,
                          dds_create_topic(participant_, request, ("rq" + base + "Request").c_str(),
                                           nullptr, nullptr),
                          qos, nullptr);
    e.reader = dds_create_reader(
        participant_,
        dds_create_topic(participant_, reply, ("rr" + base + "Reply").c_str(), nullptr, nullptr),
        qos, nullptr);
    dds_delete_qos(qos);
    if (e.writer < 0 || e.reader < 0) throw std::runtime_error("peer: cannot create " + base);
    return e;
  }

  // True once the node's request reader and reply writer are matched.
  static bool matched(const Endpoints& e, double seconds) {
    const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(seconds));
    while (Clock::now() < end) {
      dds_publication_matched_status_t pub{};
      dds_subscription_matched_status_t sub{};
      dds_get_publication_matched_status(e.writer, &pub);
      dds_get_subscription_matched_status(e.reader, &sub);
      if (pub.current_count > 0 && sub.current_count > 0) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  }

  // Writes `request` (whose header it fills: this client, the next sequence number) and waits
  // up to `seconds` for the reply with the same header, which `read` receives where DDS loaned
  // it. Replies with another header (another client's, an earlier call's) are counted in
  // `foreign_replies` and skipped.
  template <typename Request, typename Reply, typename Read>
  bool call(const Endpoints& e, Request& request, Read&& read, double seconds = 5.0) {
    request.header.client = client_id_;
    request.header.number = ++sequence_;
    if (dds_write(e.writer, &request) < 0) return false;
    return wait_reply<Reply>(e, request.header.number, std::forward<Read>(read), seconds);
  }

  template <typename Reply, typename Read>
  bool wait_reply(const Endpoints& e, std::int64_t number, Read&& read, double seconds = 5.0) {
    const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(seconds));
    while (Clock::now() < end) {
      void* samples[1] = {};
      dds_sample_info_t info;
      while (dds_take(e.reader, samples, &info, 1, 1) == 1) {
        bool done = false;
        if (info.valid_data) {
          const Reply& reply = *static_cast<const Reply*>(samples[0]);
          if (reply.header.client == client_id_ && reply.header.number == number) {
            read(reply);
            done = true;
          } else {
            ++foreign_replies;
          }
        }
        dds_return_loan(e.reader, samples, 1);
        if (done) return true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  }

  std::int64_t next_sequence() { return ++sequence_; }
  int foreign_replies = 0;

 private:
  std::uint64_t client_id_;
  std::int64_t sequence_ = 0;
  dds_entity_t participant_ = 0;
  std::deque<std::string> names_;
  std::deque<dds_topic_descriptor_t> descriptors_;
};

// What a test reads of a ParameterValue.
struct Value {
  std::uint8_t type = 0;
  bool boolean = false;
  std::int64_t integer = 0;
  double number = 0.0;
  std::string text;
  std::vector<double> numbers;
};

inline Value copy(const peer_Value& m) {
  Value v;
  v.type = m.type;
  v.boolean = m.bool_value;
  v.integer = m.integer_value;
  v.number = m.double_value;
  v.text = m.string_value ? m.string_value : "";
  v.numbers.assign(m.double_array_value._buffer,
                   m.double_array_value._buffer + m.double_array_value._length);
  return v;
}

inline std::vector<std::string> copy(const dds_sequence_string& s) {
  std::vector<std::string> out;
  for (std::uint32_t i = 0; i < s._length; ++i) out.emplace_back(s._buffer[i]);
  return out;
}

// A Parameter with storage of its own.
struct Parameter {
  std::string name;
  peer_Value value{};
  std::vector<double> numbers;
  std::string text;

  static Parameter number(std::string name, double v) {
    Parameter p;
    p.name = std::move(name);
    p.value.type = 3;
    p.value.double_value = v;
    return p;
  }
  static Parameter numbers_of(std::string name, std::vector<double> v) {
    Parameter p;
    p.name = std::move(name);
    p.value.type = 8;
    p.numbers = std::move(v);
    return p;
  }
  static Parameter boolean(std::string name, bool v) {
    Parameter p;
    p.name = std::move(name);
    p.value.type = 1;
    p.value.bool_value = v;
    return p;
  }
  static Parameter string_of(std::string name, std::string v) {
    Parameter p;
    p.name = std::move(name);
    p.value.type = 4;
    p.text = std::move(v);
    return p;
  }
  peer_Parameter message() {
    peer_Parameter m{};
    m.name = const_cast<char*>(name.c_str());
    m.value = value;
    m.value.string_value = const_cast<char*>(text.c_str());
    point(m.value.double_array_value, numbers.data(), numbers.size());
    return m;
  }
};

}  // namespace parameter_services_test
