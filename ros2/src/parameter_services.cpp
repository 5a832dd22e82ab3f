#include "parameter_services.hpp"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <deque>
#include <map>
#include <optional>
#include <thread>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/node/log_throttle.hpp>

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
// How often the values in force are compared with what /parameter_events showed (topic commands
// change parameters without a set): the longest an event lags the change.
constexpr auto kEventPoll = std::chrono::milliseconds(50);
// The services' thread's nice value (0 is the default; 19 the lowest priority).
constexpr int kServicesNice = 10;

}  // namespace

std::optional<std::string> count_fault(const char* what, std::uint64_t count, std::uint64_t limit) {
  if (count <= limit) return std::nullopt;
  return std::string(what) + ": " + std::to_string(count) + ", more than " + std::to_string(limit);
}

std::optional<std::string> length_fault(const char* what, const char* text, std::size_t limit) {
  // strnlen: the bound is checked without reading past it; the whole length is counted only for
  // the message of one that is too long.
  if (text == nullptr || strnlen(text, limit + 1) <= limit) return std::nullopt;
  std::string start;
  for (const char* c = text; *c != '\0' && start.size() < 32; ++c) {
    start += (*c >= 0x20 && *c < 0x7f) ? *c : '?';
  }
  return std::string(what) + " of " + std::to_string(std::strlen(text)) +
         " characters (beginning '" + start + "...') is longer than " + std::to_string(limit);
}

namespace {

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

// The first bound (request_limits) a request's names or prefixes break.
std::optional<std::string> names_fault(const dds_sequence_string& names, const char* what) {
  using namespace request_limits;
  if (auto fault = count_fault(what, names._length, kItems)) return fault;
  for (std::uint32_t i = 0; i < names._length; ++i) {
    const std::string item = std::string(what) + "[" + std::to_string(i) + "]";
    if (auto fault = length_fault(item.c_str(), names._buffer[i], kNameLength)) return fault;
  }
  return std::nullopt;
}

std::optional<std::string> value_fault(const ValueMessage& value, const std::string& where) {
  using namespace request_limits;
  const auto count = [&](const char* member, std::uint32_t length) {
    return count_fault((where + "." + member + " elements").c_str(), length, kArrayLength);
  };
  if (auto fault =
          length_fault((where + ".string_value").c_str(), value.string_value, kStringLength)) {
    return fault;
  }
  if (auto f = count("byte_array_value", value.byte_array_value._length)) return f;
  if (auto f = count("bool_array_value", value.bool_array_value._length)) return f;
  if (auto f = count("integer_array_value", value.integer_array_value._length)) return f;
  if (auto f = count("double_array_value", value.double_array_value._length)) return f;
  if (auto f = count("string_array_value", value.string_array_value._length)) return f;
  for (std::uint32_t i = 0; i < value.string_array_value._length; ++i) {
    const std::string item = where + ".string_array_value[" + std::to_string(i) + "]";
    if (auto fault =
            length_fault(item.c_str(), value.string_array_value._buffer[i], kStringLength)) {
      return fault;
    }
  }
  return std::nullopt;
}

std::optional<std::string> parameters_fault(
    const dds_sequence_rcl_interfaces_msg_dds__Parameter_& list) {
  using namespace request_limits;
  if (auto fault = count_fault("parameters", list._length, kItems)) return fault;
  for (std::uint32_t i = 0; i < list._length; ++i) {
    const std::string where = "parameters[" + std::to_string(i) + "]";
    if (auto fault = length_fault((where + ".name").c_str(), list._buffer[i].name, kNameLength)) {
      return fault;
    }
    if (auto fault = value_fault(list._buffer[i].value, where + ".value")) return fault;
  }
  return std::nullopt;
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

// The clients whose reply reader did not match within kMatchWait. A client that announces itself
// (clientid) but never reads replies would otherwise hold the services' thread for kMatchWait per
// request, and every other client's requests behind it: it is not waited for again for
// kForgetAfter (its replies are written at once, as to a client that names none). Bounded: a
// peer that makes up a new id per request costs one wait per id, and the record forgets the
// oldest ids first.
class ReplyWaits {
 public:
  static constexpr auto kForgetAfter = std::chrono::seconds(10);
  static constexpr std::size_t kMaxClients = 256;

  bool patient(const std::string& client, std::chrono::steady_clock::time_point now) const {
    const auto found = gave_up_.find(client);
    return found == gave_up_.end() || now - found->second > kForgetAfter;
  }
  void give_up(const std::string& client, std::chrono::steady_clock::time_point now) {
    if (gave_up_.size() >= kMaxClients) {
      auto oldest = gave_up_.begin();
      for (auto it = gave_up_.begin(); it != gave_up_.end(); ++it) {
        if (it->second < oldest->second) oldest = it;
      }
      gave_up_.erase(oldest);
    }
    gave_up_[client] = now;
  }

 private:
  std::map<std::string, std::chrono::steady_clock::time_point> gave_up_;
};

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
  ReplyWaits waits;
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

// The client id (clientid in USER_DATA, as rmw_cyclonedds_cpp's clients announce it) of the
// writer of a request (`request_writer`, matched by `service.reader`); empty if it names none or
// is gone (then the reply is written at once: it is harmless, and a client that is slow to be
// discovered still gets it).
std::string client_of(const Service& service, dds_instance_handle_t request_writer) {
  dds_builtintopic_endpoint_t* writer =
      dds_get_matched_publication_data(service.reader.get(), request_writer);
  if (writer == nullptr) return "";
  std::string client = user_data_value(writer->qos, "clientid");
  dds_builtintopic_free_endpoint(writer);
  return client;
}

// rmw_cyclonedds_cpp's check_for_response_reader: true once `client` has a reader matched by
// `service.writer`.
bool has_reply_reader(const Service& service, const std::string& client) {
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

// Requests taken from one service before the others are served: a flood on one service cannot
// keep the thread from the others.
constexpr int kPerRound = 16;

// Takes up to kPerRound requests waiting on `service` and answers each with
// `answer(request, reply)`: the request is read where DDS loaned it, the reply written with the
// request's header. Returns how many were answered (kPerRound: more may wait).
template <typename Request, typename Reply, typename Answer>
std::uint64_t serve_requests(const Service& service, ReplyWaits& waits, Answer&& answer) {
  std::uint64_t answered = 0;
  for (int taken = 0; taken < kPerRound; ++taken) {
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
      const std::string client = client_of(service, info.publication_handle);
      const auto start = std::chrono::steady_clock::now();
      if (!client.empty() && waits.patient(client, start)) {
        while (!has_reply_reader(service, client) &&
               std::chrono::steady_clock::now() < start + kMatchWait) {
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
        if (!has_reply_reader(service, client)) waits.give_up(client, start);
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
  // A storm of requests must not take CPU from the control thread (which may not run at a
  // real-time priority): on a machine with few cores the scheduler then prefers it. Raising one's
  // own nice value needs no privilege.
  if (setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), kServicesNice) != 0) {
    log(LogLevel::warn, std::string("cannot lower the parameter services' thread's priority: ") +
                            std::strerror(errno));
  }
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
    const bool more = take_requests();
    // What changed without a set (a topic's stiffness, ...), as rclcpp nodes report every change.
    const std::vector<NamedValue> changes = parameters_.changes();
    if (!changes.empty()) publish_event({}, changes);
    // Requests left for the next round do not wake the waitset again.
    if (!more) {
      dds_waitset_wait(waitset, nullptr, 0,
                       std::chrono::duration_cast<std::chrono::nanoseconds>(kEventPoll).count());
    }
  }
  dds_delete(waitset);
}

bool ParameterServices::take_requests() {
  Endpoints& e = *endpoints_;
  std::uint64_t answered = 0;
  bool more = false;  // a service had kPerRound requests: more may wait
  const auto busy = [&](std::uint64_t count) {
    more = more || count >= static_cast<std::uint64_t>(kPerRound);
    return count;
  };
  answered += busy(serve_requests<rcl_interfaces_srv_dds__ListParameters_Request_,
                                  rcl_interfaces_srv_dds__ListParameters_Response_>(
      e.list, e.waits, [&](const auto& request, auto& reply, Storage& storage) {
        static thread_local ListResult result;
        if (auto fault = names_fault(request.prefixes, "prefixes")) {
          refused("list_parameters", *fault);
          return;  // nothing listed, as for a prefix that names nothing
        }
        result = parameters_.list(strings(request.prefixes), request.depth);
        storage.strings(reply.result.names, result.names);
        storage.strings(reply.result.prefixes, result.prefixes);
      }));
  answered += busy(serve_requests<rcl_interfaces_srv_dds__GetParameters_Request_,
                                  rcl_interfaces_srv_dds__GetParameters_Response_>(
      e.get, e.waits, [&](const auto& request, auto& reply, Storage& storage) {
        static thread_local std::vector<RosValue> values;
        values.clear();
        // rclcpp answers a request it cannot answer whole with no values.
        if (auto fault = names_fault(request.names, "names")) {
          refused("get_parameters", *fault);
        } else {
          values = parameters_.get(strings(request.names)).value_or(std::vector<RosValue>{});
        }
        auto& messages = storage.values();
        for (const RosValue& value : values) messages.push_back(storage.value(value));
        point(reply.values, messages.data(), messages.size());
      }));
  answered += busy(serve_requests<rcl_interfaces_srv_dds__DescribeParameters_Request_,
                                  rcl_interfaces_srv_dds__DescribeParameters_Response_>(
      e.describe, e.waits, [&](const auto& request, auto& reply, Storage&) {
        static thread_local std::vector<RosDescriptor> descriptors;
        static thread_local std::vector<DescriptorMessage> messages;
        static thread_local std::vector<rcl_interfaces_msg_dds__FloatingPointRange_> floats;
        static thread_local std::vector<rcl_interfaces_msg_dds__IntegerRange_> integers;
        descriptors.clear();
        if (auto fault = names_fault(request.names, "names")) {
          refused("describe_parameters", *fault);
        } else {
          descriptors =
              parameters_.describe(strings(request.names)).value_or(std::vector<RosDescriptor>{});
        }
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
      }));
  answered += busy(serve_requests<rcl_interfaces_srv_dds__GetParameterTypes_Request_,
                                  rcl_interfaces_srv_dds__GetParameterTypes_Response_>(
      e.types, e.waits, [&](const auto& request, auto& reply, Storage&) {
        static thread_local std::vector<std::uint8_t> types;
        types.clear();
        if (auto fault = names_fault(request.names, "names")) {
          refused("get_parameter_types", *fault);
        } else {
          types = parameters_.types(strings(request.names)).value_or(std::vector<std::uint8_t>{});
        }
        point(reply.types, types.data(), types.size());
      }));
  // set_parameters: one result per parameter, each set on its own, in order (as rclcpp does).
  answered += busy(serve_requests<rcl_interfaces_srv_dds__SetParameters_Request_,
                                  rcl_interfaces_srv_dds__SetParameters_Response_>(
      e.set, e.waits, [&](const auto& request, auto& reply, Storage& storage) {
        static thread_local std::vector<SetResult> results;
        static thread_local std::vector<SetResultMessage> messages;
        results.clear();
        if (auto fault = parameters_fault(request.parameters)) {
          // One result per parameter as rclcpp's clients expect, unless the count itself is the
          // fault: then one, rather than as many results as the request claims.
          const SetResult refusal{false, refused("set_parameters", *fault)};
          results.assign(
              std::min<std::uint64_t>(request.parameters._length, request_limits::kItems), refusal);
          if (request.parameters._length > request_limits::kItems) results.resize(1);
        }
        for (const NamedValue& parameter :
             results.empty() ? from_message(request.parameters) : std::vector<NamedValue>{}) {
          std::vector<NamedValue> changed;
          results.push_back(parameters_.set({parameter}, &changed));
          if (results.back().successful) publish_event({}, changed);
        }
        messages.clear();
        for (const SetResult& result : results) {
          messages.push_back({result.successful, storage.c_str(result.reason)});
        }
        point(reply.results, messages.data(), messages.size());
      }));
  answered += busy(serve_requests<rcl_interfaces_srv_dds__SetParametersAtomically_Request_,
                                  rcl_interfaces_srv_dds__SetParametersAtomically_Response_>(
      e.set_atomically, e.waits, [&](const auto& request, auto& reply, Storage& storage) {
        static thread_local SetResult result;
        std::vector<NamedValue> changed;
        if (auto fault = parameters_fault(request.parameters)) {
          result = {false, refused("set_parameters_atomically", *fault)};
        } else {
          result = parameters_.set(from_message(request.parameters), &changed);
        }
        if (result.successful && !changed.empty()) publish_event({}, changed);
        reply.result.successful = result.successful;
        reply.result.reason = storage.c_str(result.reason);
      }));
  answered_ += answered;
  return more;
}

std::string ParameterServices::refused(const char* service, const std::string& fault) {
  const std::string reason = "request to " + node_ + "/" + service + " refused: " + fault +
                             " (see request_limits); nothing was changed";
  if (auto line = throttle_.line(service, cartesian_impedance::Fault{}, reason)) {
    log(LogLevel::warn, *line);
  }
  return reason;
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
