#include "parameter_services.hpp"

#include <chrono>
#include <cstring>
#include <deque>
#include <thread>

#include <cartesian_impedance/core/error.hpp>

#include "log.hpp"
#include "messages.hpp"

namespace cartesian_impedance_ros2 {

namespace {

using ValueMessage = rcl_interfaces_msg_dds__ParameterValue_;
using ParameterMessage = rcl_interfaces_msg_dds__Parameter_;
using DescriptorMessage = rcl_interfaces_msg_dds__ParameterDescriptor_;
using EventMessage = rcl_interfaces_msg_dds__ParameterEvent_;
using SetResultMessage = rcl_interfaces_msg_dds__SetParametersResult_;

// ROS 2's QoS: services (rmw_qos_profile_services_default) and /parameter_events
// (rmw_qos_profile_parameter_events).
const TopicQos kServiceQos{true, false, 10};
const TopicQos kEventQos{true, false, 1000};

// How long a reply waits for the client's reply reader to match (rmw_cyclonedds_cpp: 100 ms).
constexpr auto kMatchWait = std::chrono::milliseconds(100);

std::string text(const char* value) {
  return value == nullptr ? std::string() : std::string(value);
}

std::vector<std::string> strings(const dds_sequence_string& sequence) {
  std::vector<std::string> out;
  out.reserve(sequence._length);
  for (std::uint32_t i = 0; i < sequence._length; ++i) out.push_back(text(sequence._buffer[i]));
  return out;
}

template <typename T, typename Sequence>
std::vector<T> items(const Sequence& sequence) {
  return std::vector<T>(sequence._buffer, sequence._buffer + sequence._length);
}

RosValue from_message(const ValueMessage& m) {
  RosValue value;
  value.type = m.type;
  value.boolean = m.bool_value;
  value.integer = m.integer_value;
  value.number = m.double_value;
  value.text = text(m.string_value);
  value.bytes = items<std::uint8_t>(m.byte_array_value);
  for (std::uint32_t i = 0; i < m.bool_array_value._length; ++i) {
    value.booleans.push_back(m.bool_array_value._buffer[i] ? 1 : 0);
  }
  value.integers = items<std::int64_t>(m.integer_array_value);
  value.numbers = items<double>(m.double_array_value);
  value.texts = strings(m.string_array_value);
  return value;
}

std::vector<NamedValue> from_message(const dds_sequence_rcl_interfaces_msg_dds__Parameter_& list) {
  std::vector<NamedValue> out;
  for (std::uint32_t i = 0; i < list._length; ++i) {
    out.emplace_back(text(list._buffer[i].name), from_message(list._buffer[i].value));
  }
  return out;
}

template <typename Sequence, typename T>
void point(Sequence& sequence, T* data, std::size_t size) {
  sequence._maximum = sequence._length = static_cast<std::uint32_t>(size);
  sequence._buffer = size == 0 ? nullptr : data;
  sequence._release = false;
}

// Outgoing messages point into this storage (strings, arrays), kept until the write returns.
class Storage {
 public:
  char* c_str(const std::string& value) { return const_cast<char*>(value.c_str()); }

  void strings(dds_sequence_string& sequence, const std::vector<std::string>& values) {
    auto& pointers = string_arrays_.emplace_back();
    for (const std::string& value : values) pointers.push_back(c_str(value));
    point(sequence, pointers.data(), pointers.size());
  }

  ValueMessage value(const RosValue& v) {
    ValueMessage m{};
    m.type = v.type;
    m.bool_value = v.boolean;
    m.integer_value = v.integer;
    m.double_value = v.number;
    m.string_value = c_str(v.text);
    point(m.byte_array_value, const_cast<std::uint8_t*>(v.bytes.data()), v.bytes.size());
    auto& booleans = bool_arrays_.emplace_back(std::make_unique<bool[]>(v.booleans.size() + 1));
    for (std::size_t i = 0; i < v.booleans.size(); ++i) booleans[i] = v.booleans[i] != 0;
    point(m.bool_array_value, booleans.get(), v.booleans.size());
    point(m.integer_array_value, const_cast<std::int64_t*>(v.integers.data()), v.integers.size());
    point(m.double_array_value, const_cast<double*>(v.numbers.data()), v.numbers.size());
    strings(m.string_array_value, v.texts);
    return m;
  }

  void parameters(dds_sequence_rcl_interfaces_msg_dds__Parameter_& sequence,
                  const std::vector<NamedValue>& values) {
    auto& list = parameter_arrays_.emplace_back();
    for (const auto& [name, value] : values) list.push_back({c_str(name), this->value(value)});
    point(sequence, list.data(), list.size());
  }

  std::vector<ValueMessage>& values() { return value_arrays_.emplace_back(); }

 private:
  // Deques of vectors: an element's address stays valid while more are added.
  std::deque<std::vector<char*>> string_arrays_;
  std::deque<std::unique_ptr<bool[]>> bool_arrays_;
  std::deque<std::vector<ParameterMessage>> parameter_arrays_;
  std::deque<std::vector<ValueMessage>> value_arrays_;
};

std::string user_data_value(const dds_qos_t* qos, const std::string& key) {
  void* data = nullptr;
  size_t size = 0;
  if (qos == nullptr || !dds_qget_userdata(qos, &data, &size) || data == nullptr) return "";
  const std::string all(static_cast<const char*>(data), size);
  dds_free(data);
  const std::string needle = key + "=";
  std::size_t at = 0;
  while (at < all.size()) {
    const std::size_t end = all.find(';', at);
    const std::string item =
        all.substr(at, end == std::string::npos ? std::string::npos : end - at);
    if (item.rfind(needle, 0) == 0) return item.substr(needle.size());
    if (end == std::string::npos) break;
    at = end + 1;
  }
  return "";
}

}  // namespace

// One service: its request reader and reply writer.
struct Service {
  Entity reader;
  Entity writer;
};

struct ParameterServices::Endpoints {
  Service list, get, set, set_atomically, describe, types;
  Entity events;
  Entity wake;  // guard condition: stop
};

namespace {

template <typename Request, typename Reply>
Service make_service(const Participant& participant, const std::string& node,
                     const std::string& name) {
  const std::string service = node + "/" + name;
  Service s;
  const auto endpoint = [&](const dds_topic_descriptor_t* type, const char* hash,
                            const std::string& topic, bool reader) {
    const dds_entity_t t = find_or_create_topic(participant, type, topic);
    dds_qos_t* qos = endpoint_qos(kServiceQos, hash);
    const dds_entity_t e = reader ? dds_create_reader(participant.get(), t, qos, nullptr)
                                  : dds_create_writer(participant.get(), t, qos, nullptr);
    dds_delete_qos(qos);
    return Entity(check(e, (reader ? "reader of " : "writer of ") + topic));
  };
  s.reader = endpoint(MessageType<Request>::descriptor(), MessageType<Request>::type_hash,
                      "rq" + service + "Request", true);
  s.writer = endpoint(MessageType<Reply>::descriptor(), MessageType<Reply>::type_hash,
                      "rr" + service + "Reply", false);
  return s;
}

// rmw_cyclonedds_cpp's check_for_response_reader: true once the client that wrote the request
// (`request_writer`, matched by `service.reader`) has a reader matched by `service.writer`, or if
// the client does not name itself (clientid), or is gone (then the reply is written anyway: it is
// harmless, and a client that is slow to be discovered still gets it).
bool client_can_receive(const Service& service, dds_instance_handle_t request_writer) {
  dds_builtintopic_endpoint_t* writer =
      dds_get_matched_publication_data(service.reader.get(), request_writer);
  if (writer == nullptr) return true;
  const std::string client = user_data_value(writer->qos, "clientid");
  dds_builtintopic_free_endpoint(writer);
  if (client.empty()) return true;
  dds_instance_handle_t readers[64];
  const dds_return_t count = dds_get_matched_subscriptions(service.writer.get(), readers, 64);
  for (dds_return_t i = 0; i < count && i < 64; ++i) {
    dds_builtintopic_endpoint_t* reader =
        dds_get_matched_subscription_data(service.writer.get(), readers[i]);
    if (reader == nullptr) continue;
    const bool same = user_data_value(reader->qos, "clientid") == client;
    dds_builtintopic_free_endpoint(reader);
    if (same) return true;
  }
  return false;
}

// Takes every request waiting on `service` and answers each with `answer(request, reply)`:
// the request is read where DDS loaned it, the reply written with the request's header.
template <typename Request, typename Reply, typename Answer>
std::uint64_t serve_requests(const Service& service, Answer&& answer) {
  std::uint64_t answered = 0;
  for (;;) {
    void* samples[1] = {};
    dds_sample_info_t info;
    if (dds_take(service.reader.get(), samples, &info, 1, 1) <= 0) break;
    if (info.valid_data) {
      const Request& request = *static_cast<const Request*>(samples[0]);
      Reply reply{};
      reply.cdds_request_header_guid = request.cdds_request_header_guid;
      reply.cdds_request_header_seq = request.cdds_request_header_seq;
      Storage storage;
      answer(request, reply, storage);
      const auto deadline = std::chrono::steady_clock::now() + kMatchWait;
      while (!client_can_receive(service, info.publication_handle) &&
             std::chrono::steady_clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
      if (dds_write(service.writer.get(), &reply) < 0) {
        log(LogLevel::warn, "DDS: cannot write a parameter service reply");
      }
      ++answered;
    }
    dds_return_loan(service.reader.get(), samples, 1);
  }
  return answered;
}

}  // namespace

ParameterServices::ParameterServices(const Participant& participant, const std::string& node,
                                     const std::string& events_topic, NodeParameters& parameters)
    : node_(node), parameters_(parameters), endpoints_(std::make_unique<Endpoints>()) {
  Endpoints& e = *endpoints_;
  e.list = make_service<rcl_interfaces_srv_dds__ListParameters_Request_,
                        rcl_interfaces_srv_dds__ListParameters_Response_>(participant, node,
                                                                          "list_parameters");
  e.get = make_service<rcl_interfaces_srv_dds__GetParameters_Request_,
                       rcl_interfaces_srv_dds__GetParameters_Response_>(participant, node,
                                                                        "get_parameters");
  e.set = make_service<rcl_interfaces_srv_dds__SetParameters_Request_,
                       rcl_interfaces_srv_dds__SetParameters_Response_>(participant, node,
                                                                        "set_parameters");
  e.set_atomically = make_service<rcl_interfaces_srv_dds__SetParametersAtomically_Request_,
                                  rcl_interfaces_srv_dds__SetParametersAtomically_Response_>(
      participant, node, "set_parameters_atomically");
  e.describe = make_service<rcl_interfaces_srv_dds__DescribeParameters_Request_,
                            rcl_interfaces_srv_dds__DescribeParameters_Response_>(
      participant, node, "describe_parameters");
  e.types = make_service<rcl_interfaces_srv_dds__GetParameterTypes_Request_,
                         rcl_interfaces_srv_dds__GetParameterTypes_Response_>(
      participant, node, "get_parameter_types");
  const dds_entity_t topic = find_or_create_topic(
      participant, MessageType<EventMessage>::descriptor(), "rt" + events_topic);
  dds_qos_t* qos = endpoint_qos(kEventQos, MessageType<EventMessage>::type_hash);
  const dds_entity_t writer = dds_create_writer(participant.get(), topic, qos, nullptr);
  dds_delete_qos(qos);
  e.events = Entity(check(writer, "writer of rt" + events_topic));
  e.wake = Entity(check(dds_create_guardcondition(participant.get()), "guard condition"));
}

ParameterServices::~ParameterServices() {
  stop();
}

std::vector<dds_entity_t> ParameterServices::readers() const {
  const Endpoints& e = *endpoints_;
  return {e.list.reader.get(),           e.get.reader.get(),      e.set.reader.get(),
          e.set_atomically.reader.get(), e.describe.reader.get(), e.types.reader.get()};
}

std::vector<dds_entity_t> ParameterServices::writers() const {
  const Endpoints& e = *endpoints_;
  return {e.list.writer.get(),     e.get.writer.get(),
          e.set.writer.get(),      e.set_atomically.writer.get(),
          e.describe.writer.get(), e.types.writer.get(),
          e.events.get()};
}

void ParameterServices::start() {
  if (thread_.joinable()) return;
  stop_ = false;
  publish_event(parameters_.all(), {});
  thread_ = std::thread([this] { serve(); });
}

void ParameterServices::stop() {
  stop_ = true;
  if (endpoints_ && endpoints_->wake.get() > 0)
    dds_set_guardcondition(endpoints_->wake.get(), true);
  if (thread_.joinable()) thread_.join();
}

void ParameterServices::serve() {
  const dds_entity_t waitset = dds_create_waitset(dds_get_participant(endpoints_->wake.get()));
  if (waitset < 0) {
    log(LogLevel::error, std::string("DDS: cannot create the parameter services' waitset: ") +
                             dds_strretcode(waitset));
    return;
  }
  for (const dds_entity_t reader : readers()) {
    dds_set_status_mask(reader, DDS_DATA_AVAILABLE_STATUS);
    dds_waitset_attach(waitset, reader, reader);
  }
  dds_waitset_attach(waitset, endpoints_->wake.get(), endpoints_->wake.get());
  while (!stop_) {
    take_requests();
    dds_waitset_wait(waitset, nullptr, 0, DDS_MSECS(100));
  }
  dds_delete(waitset);
}

void ParameterServices::take_requests() {
  Endpoints& e = *endpoints_;
  std::uint64_t answered = 0;
  answered += serve_requests<rcl_interfaces_srv_dds__ListParameters_Request_,
                             rcl_interfaces_srv_dds__ListParameters_Response_>(
      e.list, [&](const auto& request, auto& reply, Storage& storage) {
        static thread_local ListResult result;
        result = parameters_.list(strings(request.prefixes), request.depth);
        storage.strings(reply.result.names, result.names);
        storage.strings(reply.result.prefixes, result.prefixes);
      });
  answered += serve_requests<rcl_interfaces_srv_dds__GetParameters_Request_,
                             rcl_interfaces_srv_dds__GetParameters_Response_>(
      e.get, [&](const auto& request, auto& reply, Storage& storage) {
        static thread_local std::vector<RosValue> values;
        values = parameters_.get(strings(request.names)).value_or(std::vector<RosValue>{});
        auto& messages = storage.values();
        for (const RosValue& value : values) messages.push_back(storage.value(value));
        point(reply.values, messages.data(), messages.size());
      });
  answered += serve_requests<rcl_interfaces_srv_dds__DescribeParameters_Request_,
                             rcl_interfaces_srv_dds__DescribeParameters_Response_>(
      e.describe, [&](const auto& request, auto& reply, Storage&) {
        static thread_local std::vector<RosDescriptor> descriptors;
        static thread_local std::vector<DescriptorMessage> messages;
        static thread_local std::vector<rcl_interfaces_msg_dds__FloatingPointRange_> floats;
        static thread_local std::vector<rcl_interfaces_msg_dds__IntegerRange_> integers;
        descriptors =
            parameters_.describe(strings(request.names)).value_or(std::vector<RosDescriptor>{});
        messages.assign(descriptors.size(), DescriptorMessage{});
        floats.assign(descriptors.size(), {});
        integers.assign(descriptors.size(), {});
        for (std::size_t i = 0; i < descriptors.size(); ++i) {
          const RosDescriptor& d = descriptors[i];
          DescriptorMessage& m = messages[i];
          m.name = const_cast<char*>(d.name.c_str());
          m.type = d.type;
          m.description = const_cast<char*>(d.description.c_str());
          m.additional_constraints = const_cast<char*>(d.additional_constraints.c_str());
          m.read_only = d.read_only;
          m.dynamic_typing = false;
          if (d.floating_point_range) {
            floats[i] = {d.floating_point_range->first, d.floating_point_range->second, 0.0};
            point(m.floating_point_range, &floats[i], 1);
          }
          if (d.integer_range) {
            integers[i] = {d.integer_range->first, d.integer_range->second, 0};
            point(m.integer_range, &integers[i], 1);
          }
        }
        point(reply.descriptors, messages.data(), messages.size());
      });
  answered += serve_requests<rcl_interfaces_srv_dds__GetParameterTypes_Request_,
                             rcl_interfaces_srv_dds__GetParameterTypes_Response_>(
      e.types, [&](const auto& request, auto& reply, Storage&) {
        static thread_local std::vector<std::uint8_t> types;
        types = parameters_.types(strings(request.names)).value_or(std::vector<std::uint8_t>{});
        point(reply.types, types.data(), types.size());
      });
  // set_parameters: one result per parameter, each set on its own, in order (as rclcpp does).
  answered += serve_requests<rcl_interfaces_srv_dds__SetParameters_Request_,
                             rcl_interfaces_srv_dds__SetParameters_Response_>(
      e.set, [&](const auto& request, auto& reply, Storage& storage) {
        static thread_local std::vector<SetResult> results;
        static thread_local std::vector<SetResultMessage> messages;
        results.clear();
        for (const NamedValue& parameter : from_message(request.parameters)) {
          std::vector<NamedValue> changed;
          results.push_back(parameters_.set({parameter}, &changed));
          if (results.back().successful) publish_event({}, changed);
        }
        messages.clear();
        for (const SetResult& result : results) {
          messages.push_back({result.successful, storage.c_str(result.reason)});
        }
        point(reply.results, messages.data(), messages.size());
      });
  answered += serve_requests<rcl_interfaces_srv_dds__SetParametersAtomically_Request_,
                             rcl_interfaces_srv_dds__SetParametersAtomically_Response_>(
      e.set_atomically, [&](const auto& request, auto& reply, Storage& storage) {
        static thread_local SetResult result;
        std::vector<NamedValue> changed;
        result = parameters_.set(from_message(request.parameters), &changed);
        if (result.successful && !changed.empty()) publish_event({}, changed);
        reply.result.successful = result.successful;
        reply.result.reason = storage.c_str(result.reason);
      });
  answered_ += answered;
}

void ParameterServices::publish_event(const std::vector<NamedValue>& fresh,
                                      const std::vector<NamedValue>& changed) {
  Storage storage;
  EventMessage event{};
  event.stamp = stamp_now();
  event.node = storage.c_str(node_);
  storage.parameters(event.new_parameters, fresh);
  storage.parameters(event.changed_parameters, changed);
  point(event.deleted_parameters, static_cast<ParameterMessage*>(nullptr), 0);
  if (dds_write(endpoints_->events.get(), &event) < 0) {
    log(LogLevel::warn, "DDS: cannot write a parameter event");
  }
}

}  // namespace cartesian_impedance_ros2
