#pragma once
// What the parameter services' end-to-end tests share: the independent client's six services of
// the node (peer.hpp), /parameter_events, and the node's full_state (the node's own types: what
// the arm does is not the subject of the independence).

#include <algorithm>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "harness.hpp"
#include "peer.hpp"

namespace parameter_services_test {

namespace test = cartesian_impedance_ros2::test;

inline const std::string kNode = "/cartesian_impedance_controller";

inline std::string sim_params() {
  return test::repository() + "/ros2/config/sim_panda.yaml";
}

// The six services of the node, on one peer.
struct Services {
  explicit Services(Peer& peer)
      : list(peer.service(kNode, "list_parameters",
                          peer.named(peer_ListRequest_desc, request_type("ListParameters")),
                          peer.named(peer_ListReply_desc, reply_type("ListParameters")))),
        get(peer.service(kNode, "get_parameters",
                         peer.named(peer_NamesRequest_desc, request_type("GetParameters")),
                         peer.named(peer_GetReply_desc, reply_type("GetParameters")))),
        set(peer.service(kNode, "set_parameters",
                         peer.named(peer_SetRequest_desc, request_type("SetParameters")),
                         peer.named(peer_SetReply_desc, reply_type("SetParameters")))),
        set_atomically(peer.service(
            kNode, "set_parameters_atomically",
            peer.named(peer_SetRequest_desc, request_type("SetParametersAtomically")),
            peer.named(peer_SetAtomicallyReply_desc, reply_type("SetParametersAtomically")))),
        describe(
            peer.service(kNode, "describe_parameters",
                         peer.named(peer_NamesRequest_desc, request_type("DescribeParameters")),
                         peer.named(peer_DescribeReply_desc, reply_type("DescribeParameters")))),
        types(peer.service(kNode, "get_parameter_types",
                           peer.named(peer_NamesRequest_desc, request_type("GetParameterTypes")),
                           peer.named(peer_TypesReply_desc, reply_type("GetParameterTypes")))),
        peer_(peer) {}

  bool matched(double seconds) {
    for (const Peer::Endpoints* e : {&list, &get, &set, &set_atomically, &describe, &types}) {
      if (!Peer::matched(*e, seconds)) return false;
    }
    return true;
  }

  std::optional<std::vector<Value>> get_values(std::vector<std::string> names) {
    std::vector<char*> pointers;
    for (std::string& name : names) pointers.push_back(name.data());
    peer_NamesRequest request{};
    point(request.names, pointers.data(), pointers.size());
    std::vector<Value> values;
    const bool answered =
        peer_.call<peer_NamesRequest, peer_GetReply>(get, request, [&](const peer_GetReply& r) {
          for (std::uint32_t i = 0; i < r.values._length; ++i)
            values.push_back(copy(r.values._buffer[i]));
        });
    if (!answered) return std::nullopt;
    return values;
  }

  // describe_parameters: name, description and read_only of each (nullopt: no reply).
  struct Description {
    std::string name;
    std::string description;
    bool read_only = false;
  };
  std::optional<std::vector<Description>> describe_values(std::vector<std::string> names) {
    std::vector<char*> pointers;
    for (std::string& name : names) pointers.push_back(name.data());
    peer_NamesRequest request{};
    point(request.names, pointers.data(), pointers.size());
    std::vector<Description> out;
    const bool answered = peer_.call<peer_NamesRequest, peer_DescribeReply>(
        describe, request, [&](const peer_DescribeReply& r) {
          for (std::uint32_t i = 0; i < r.descriptors._length; ++i) {
            const peer_Descriptor& m = r.descriptors._buffer[i];
            out.push_back({m.name, m.description, m.read_only});
          }
        });
    if (!answered) return std::nullopt;
    return out;
  }

  struct Results {
    bool answered = false;
    std::vector<std::pair<bool, std::string>> results;
  };
  Results set_values(std::vector<Parameter> parameters, bool atomically = false) {
    std::vector<peer_Parameter> messages;
    for (Parameter& p : parameters) messages.push_back(p.message());
    peer_SetRequest request{};
    point(request.parameters, messages.data(), messages.size());
    Results out;
    if (atomically) {
      out.answered = peer_.call<peer_SetRequest, peer_SetAtomicallyReply>(
          set_atomically, request, [&](const peer_SetAtomicallyReply& r) {
            out.results.emplace_back(r.result.successful, r.result.reason);
          });
    } else {
      out.answered =
          peer_.call<peer_SetRequest, peer_SetReply>(set, request, [&](const peer_SetReply& r) {
            for (std::uint32_t i = 0; i < r.results._length; ++i) {
              out.results.emplace_back(r.results._buffer[i].successful,
                                       r.results._buffer[i].reason);
            }
          });
    }
    return out;
  }

  Peer::Endpoints list, get, set, set_atomically, describe, types;

 private:
  Peer& peer_;
};

// The events of /parameter_events, copied out.
struct Event {
  std::string node;
  std::vector<std::pair<std::string, Value>> fresh, changed;
  std::size_t deleted = 0;
};

class Events {
 public:
  explicit Events(Peer& peer) {
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1000);
    const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
    dds_qset_data_representation(qos, 1, &xcdr1);
    const dds_entity_t topic =
        dds_create_topic(peer.participant(),
                         peer.named(peer_Event_desc, "rcl_interfaces::msg::dds_::ParameterEvent_"),
                         "rt/parameter_events", nullptr, nullptr);
    reader_ = dds_create_reader(peer.participant(), topic, qos, nullptr);
    dds_delete_qos(qos);
  }
  // Takes what arrived.
  const std::vector<Event>& poll() {
    void* samples[1] = {};
    dds_sample_info_t info;
    while (dds_take(reader_, samples, &info, 1, 1) == 1) {
      if (info.valid_data) {
        const peer_Event& m = *static_cast<const peer_Event*>(samples[0]);
        Event e;
        e.node = m.node;
        for (std::uint32_t i = 0; i < m.new_parameters._length; ++i) {
          e.fresh.emplace_back(m.new_parameters._buffer[i].name,
                               copy(m.new_parameters._buffer[i].value));
        }
        for (std::uint32_t i = 0; i < m.changed_parameters._length; ++i) {
          e.changed.emplace_back(m.changed_parameters._buffer[i].name,
                                 copy(m.changed_parameters._buffer[i].value));
        }
        e.deleted = m.deleted_parameters._length;
        events_.push_back(std::move(e));
      }
      dds_return_loan(reader_, samples, 1);
    }
    return events_;
  }
  bool matched(double seconds) {
    return test::eventually(seconds, [&] {
      dds_subscription_matched_status_t s{};
      dds_get_subscription_matched_status(reader_, &s);
      return s.current_count > 0;
    });
  }

 private:
  dds_entity_t reader_ = 0;
  std::vector<Event> events_;
};

// The node's full_state: position of the flange and commanded stiffness (the node's own types:
// what the arm does is not the subject of the independence).
struct ArmState {
  std::string status;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double stiffness_x = 0.0;
  double period_p50_us = 0.0;
  double period_p99_us = 0.0;
  std::uint64_t overruns = 0;
};

inline ArmState copy_state(const cartesian_impedance_ros2::FullState& m) {
  ArmState s;
  s.status = m.status;
  s.position = {m.current_pose.position.x, m.current_pose.position.y, m.current_pose.position.z};
  s.stiffness_x = m.commanded_cartesian_stiffness.force.x;
  s.period_p50_us = m.period_p50_us;
  s.period_p99_us = m.period_p99_us;
  s.overruns = m.overruns;
  return s;
}

using StateReader = test::Latest<cartesian_impedance_ros2::FullState,
                                 ArmState (*)(const cartesian_impedance_ros2::FullState&)>;

inline const cartesian_impedance_ros2::Participant& node_participant() {
  test::use_private_domain();
  static const cartesian_impedance_ros2::Participant instance;
  return instance;
}

inline bool contains(const std::vector<std::string>& list, const std::string& item) {
  return std::find(list.begin(), list.end(), item) != list.end();
}

}  // namespace parameter_services_test
