// ROS 2's parameter services on the node, end to end over DDS: an independent client (peer.hpp,
// the test's own types with the request header framed by the test) calls all six services of the
// node in sim mode and checks the replies, the parameter events (topic commands' too), a fuzz of
// malformed and hostile requests (the bounds every request is held to, a storm and a client
// without a reply reader are in request_bounds_test.cpp), and the closed loop (a stiffness set over
// the service changes how far a push moves the arm; a refused one changes nothing). Plus golden
// bytes of one request and one reply of the node's generated types, header included.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <random>
#include <thread>

#include "cdr_writer.hpp"
#include "cyclone_codec.hpp"
#include "harness.hpp"
#include "parameter_services.hpp"
#include "peer.hpp"
#include "services.hpp"

namespace parameter_services_test {
namespace {

using test::NodeProcess;

// ---- (a) the six services, from the independent client -------------------------------------

TEST(ParameterServices, AnswersEachServiceAsRclcppDoes) {
  test::use_private_domain();
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  Peer peer(0x5eed000000000001ull);
  Events events(peer);
  Services services(peer);
  ASSERT_TRUE(services.matched(15.0)) << node.log();
  ASSERT_TRUE(events.matched(5.0));

  // list_parameters: everything, then one prefix one level deep.
  std::vector<std::string> names, prefixes;
  {
    peer_ListRequest request{};
    ASSERT_TRUE((peer.call<peer_ListRequest, peer_ListReply>(services.list, request,
                                                             [&](const peer_ListReply& r) {
                                                               names = copy(r.names);
                                                               prefixes = copy(r.prefixes);
                                                             })));
  }
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));
  for (const char* name :
       {"stiffness.translation", "limits.stiffness.translation.max", "mode", "control_rate",
        "base_link", "use_sim_time", "urdf_path", "ros_distro"}) {
    EXPECT_TRUE(contains(names, name)) << name;
  }
  EXPECT_TRUE(contains(prefixes, "stiffness"));
  EXPECT_TRUE(contains(prefixes, "limits.stiffness.translation"));
  {
    std::string prefix = "limits";
    std::vector<char*> pointers = {prefix.data()};
    peer_ListRequest request{};
    point(request.prefixes, pointers.data(), 1);
    request.depth = 2;  // limits.x.y, not limits.x.y.z
    ASSERT_TRUE((peer.call<peer_ListRequest, peer_ListReply>(
        services.list, request, [&](const peer_ListReply& r) { names = copy(r.names); })));
  }
  ASSERT_FALSE(names.empty());
  for (const std::string& name : names) {
    EXPECT_EQ(name.rfind("limits.", 0), 0u) << name;
    EXPECT_LE(std::count(name.begin(), name.end(), '.'), 2) << name;
  }
  EXPECT_FALSE(contains(names, "limits.stiffness.translation.max"));

  // get_parameters: types as ROS 2's, values as configured (config/sim_panda.yaml).
  const auto t0 = Clock::now();
  const auto values = services.get_values(
      {"stiffness.translation", "mode", "control_rate", "realtime_priority", "publish_tf"});
  const double round_trip_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  ASSERT_TRUE(values);
  ASSERT_EQ(values->size(), 5u);
  EXPECT_EQ((*values)[0].type, 8);  // double[]
  EXPECT_EQ((*values)[0].numbers.size(), 3u);
  EXPECT_EQ((*values)[1].type, 4);
  EXPECT_EQ((*values)[1].text, "sim");
  EXPECT_EQ((*values)[2].type, 3);
  EXPECT_EQ((*values)[2].number, 1000.0);
  EXPECT_EQ((*values)[3].type, 2);
  EXPECT_EQ((*values)[4].type, 1);
  std::printf("get_parameters round trip: %.2f ms\n", round_trip_ms);
  // An unknown name: rclcpp answers no values at all.
  const auto unknown = services.get_values({"stiffness.translation", "no.such.parameter"});
  ASSERT_TRUE(unknown);
  EXPECT_TRUE(unknown->empty());

  // describe_parameters: unit and range of a table row, read_only of a setting.
  {
    std::string a = "stiffness.translation", b = "mode", c = "realtime_priority";
    std::vector<char*> pointers = {a.data(), b.data(), c.data()};
    peer_NamesRequest request{};
    point(request.names, pointers.data(), pointers.size());
    struct D {
      std::string name, description, constraints;
      std::uint8_t type;
      bool read_only;
      std::vector<std::pair<double, double>> floats;
      std::vector<std::pair<std::int64_t, std::int64_t>> integers;
    };
    std::vector<D> d;
    ASSERT_TRUE((peer.call<peer_NamesRequest, peer_DescribeReply>(
        services.describe, request, [&](const peer_DescribeReply& r) {
          for (std::uint32_t i = 0; i < r.descriptors._length; ++i) {
            const peer_Descriptor& m = r.descriptors._buffer[i];
            D x{m.name, m.description, m.additional_constraints, m.type, m.read_only, {}, {}};
            for (std::uint32_t j = 0; j < m.floating_point_range._length; ++j) {
              x.floats.emplace_back(m.floating_point_range._buffer[j].from_value,
                                    m.floating_point_range._buffer[j].to_value);
            }
            for (std::uint32_t j = 0; j < m.integer_range._length; ++j) {
              x.integers.emplace_back(m.integer_range._buffer[j].from_value,
                                      m.integer_range._buffer[j].to_value);
            }
            d.push_back(x);
          }
        })));
    ASSERT_EQ(d.size(), 3u);
    const cartesian_impedance::ParameterInfo& row =
        cartesian_impedance::parameter_info("stiffness.translation");
    EXPECT_EQ(d[0].name, "stiffness.translation");
    EXPECT_EQ(d[0].type, 8);
    EXPECT_FALSE(d[0].read_only);
    EXPECT_NE(d[0].description.find("N/m"), std::string::npos) << d[0].description;
    EXPECT_NE(d[0].constraints.find(row.range_text()), std::string::npos) << d[0].constraints;
    ASSERT_EQ(d[0].floats.size(), 1u);
    EXPECT_EQ(d[0].floats[0], std::make_pair(row.min, row.max));
    EXPECT_TRUE(d[1].read_only);
    EXPECT_EQ(d[1].type, 4);
    ASSERT_EQ(d[2].integers.size(), 1u);
    EXPECT_EQ(d[2].integers[0], (std::pair<std::int64_t, std::int64_t>(0, 99)));
  }

  // get_parameter_types.
  {
    std::string a = "stiffness.translation", b = "publish_rate", c = "stiffness.frame";
    std::vector<char*> pointers = {a.data(), b.data(), c.data()};
    peer_NamesRequest request{};
    point(request.names, pointers.data(), pointers.size());
    std::vector<std::uint8_t> types;
    ASSERT_TRUE((peer.call<peer_NamesRequest, peer_TypesReply>(
        services.types, request, [&](const peer_TypesReply& r) {
          types.assign(r.types._buffer, r.types._buffer + r.types._length);
        })));
    EXPECT_EQ(types, (std::vector<std::uint8_t>{8, 3, 4}));
    std::string d = "no.such.parameter";
    pointers.push_back(d.data());
    point(request.names, pointers.data(), pointers.size());
    types = {1};
    ASSERT_TRUE((peer.call<peer_NamesRequest, peer_TypesReply>(
        services.types, request, [&](const peer_TypesReply& r) {
          types.assign(r.types._buffer, r.types._buffer + r.types._length);
        })));
    EXPECT_TRUE(types.empty());  // an unknown name: no types at all, as rclcpp
  }

  // set_parameters: one result per parameter, each on its own. Sets wait for the controller to
  // run (a start resets what was queued before it); queries are answered from the start.
  StateReader state(node_participant(), "rt" + kNode + "/full_state", &copy_state);
  ASSERT_TRUE(state.wait(15.0, [](const ArmState& s) { return s.status == "ok"; })) << node.log();
  const double k = 777.0;
  const auto t1 = Clock::now();
  auto set = services.set_values({Parameter::numbers_of("stiffness.translation", {k, k, k}),
                                  Parameter::string_of("mode", "topics"),
                                  Parameter::number("stiffness.rotation", -5.0)});
  const double set_ms = std::chrono::duration<double, std::milli>(Clock::now() - t1).count();
  std::printf(
      "set_parameters round trip (one accepted, applied by the loop; two refused): %.2f ms\n",
      set_ms);
  ASSERT_TRUE(set.answered);
  ASSERT_EQ(set.results.size(), 3u);
  EXPECT_TRUE(set.results[0].first) << set.results[0].second;
  EXPECT_FALSE(set.results[1].first);
  EXPECT_NE(set.results[1].second.find("read-only"), std::string::npos) << set.results[1].second;
  EXPECT_FALSE(set.results[2].first);
  // The decoder's message: the field, the value, the bound.
  EXPECT_NE(set.results[2].second.find("stiffness.rotation"), std::string::npos);
  EXPECT_NE(set.results[2].second.find("-5"), std::string::npos) << set.results[2].second;
  auto now = services.get_values({"stiffness.translation", "stiffness.rotation", "mode"});
  ASSERT_TRUE(now && now->size() == 3u);
  EXPECT_EQ((*now)[0].numbers, (std::vector<double>{k, k, k}));
  EXPECT_EQ((*now)[2].text, "sim");
  const std::vector<double> rotation = (*now)[1].numbers;

  // set_parameters_atomically: one bad value refuses the whole request.
  set = services.set_values({Parameter::numbers_of("stiffness.translation", {100, 100, 100}),
                             Parameter::number("stiffness.rotation", -1.0)},
                            true);
  ASSERT_TRUE(set.answered);
  ASSERT_EQ(set.results.size(), 1u);
  EXPECT_FALSE(set.results[0].first);
  EXPECT_NE(set.results[0].second.find("stiffness.rotation"), std::string::npos);
  now = services.get_values({"stiffness.translation", "stiffness.rotation"});
  ASSERT_TRUE(now && now->size() == 2u);
  EXPECT_EQ((*now)[0].numbers, (std::vector<double>{k, k, k}));
  EXPECT_EQ((*now)[1].numbers, rotation);
  set = services.set_values({Parameter::number("stiffness.translation", 600.0),
                             Parameter::number("stiffness.rotation", 40.0)},
                            true);
  ASSERT_TRUE(set.answered && set.results.size() == 1u);
  EXPECT_TRUE(set.results[0].first) << set.results[0].second;
  now = services.get_values({"stiffness.translation", "stiffness.rotation"});
  ASSERT_TRUE(now && now->size() == 2u);
  EXPECT_EQ((*now)[0].numbers, (std::vector<double>{600, 600, 600}));
  EXPECT_EQ((*now)[1].numbers, (std::vector<double>{40, 40, 40}));

  // /parameter_events: every parameter as new at the start (if this reader matched in time),
  // then each accepted set as changed, by the node's fully-qualified name.
  ASSERT_TRUE(test::eventually(2.0, [&] {
    const auto& all = events.poll();
    return std::count_if(all.begin(), all.end(),
                         [](const Event& e) { return !e.changed.empty(); }) >= 2;
  }));
  std::vector<Event> changes;
  for (const Event& e : events.poll()) {
    EXPECT_EQ(e.node, kNode);
    EXPECT_EQ(e.deleted, 0u);
    if (!e.changed.empty()) changes.push_back(e);
  }
  ASSERT_EQ(changes.size(), 2u);  // the refused sets published nothing
  ASSERT_EQ(changes[0].changed.size(), 1u);
  EXPECT_EQ(changes[0].changed[0].first, "stiffness.translation");
  EXPECT_EQ(changes[0].changed[0].second.numbers, (std::vector<double>{k, k, k}));
  ASSERT_EQ(changes[1].changed.size(), 2u);
  EXPECT_EQ(changes[1].changed[1].second.numbers, (std::vector<double>{40, 40, 40}));

  // Another client's header is never answered to this one.
  EXPECT_EQ(peer.foreign_replies, 0);
  EXPECT_TRUE(node.running()) << node.log();
}

// Two clients on the same services: each gets its own replies only (by the header's client id).
TEST(ParameterServices, EachClientGetsItsOwnReplies) {
  test::use_private_domain();
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  Peer a(0xa11ce00000000001ull), b(0xb0b0000000000002ull);
  Services sa(a), sb(b);
  ASSERT_TRUE(sa.matched(15.0) && sb.matched(5.0)) << node.log();
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(sa.get_values({"mode"}));
    ASSERT_TRUE(sb.get_values({"control_rate"}));
  }
  // Both read every reply on the topic; the other's are skipped by the header.
  EXPECT_GT(a.foreign_replies + b.foreign_replies, 0);
}

// ---- (c) fuzz: malformed bytes and hostile requests ----------------------------------------

// The payload of a good set_parameters request (header and fields, no encapsulation header),
// hand-encoded: stiffness.translation = [v, v, v].
std::vector<uint8_t> good_set_request(double v) {
  ros2_messages_test::CdrWriter w;
  w.uint64(0);  // client id: patched by the raw writer's count
  w.int64(1);
  w.sequence_length(1);
  w.string("stiffness.translation");
  w.octet(8);
  w.boolean(false);
  w.int64(0);
  w.float64(0.0);
  w.string("");
  for (int i = 0; i < 3; ++i) w.sequence_length(0);
  w.sequence_length(3);
  for (int i = 0; i < 3; ++i) w.float64(v);
  w.sequence_length(0);
  std::vector<uint8_t> bytes = w.bytes();
  bytes.resize(bytes.size() - bytes[3]);  // the final padding
  return {bytes.begin() + 4, bytes.end()};
}

TEST(ParameterServices, MalformedAndHostileRequestsLeaveTheNodeAnswering) {
  test::use_private_domain();
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  StateReader state(node_participant(), "rt" + kNode + "/full_state", &copy_state);
  ASSERT_TRUE(state.wait(15.0, [](const ArmState& s) { return s.status == "ok"; })) << node.log();

  // Malformed bytes: a writer of the raw type under set_parameters' request type name. Its
  // 4-byte count is where the node reads the low half of the client id, so any bytes after it
  // reach the node's deserializer as a request: random ones, every truncation of a good request,
  // and the good request with random bytes changed.
  Peer raw(0);
  const dds_entity_t raw_writer = [&] {
    dds_qos_t* qos = raw.service_qos();
    const dds_entity_t topic =
        dds_create_topic(raw.participant(), raw.named(peer_Raw_desc, request_type("SetParameters")),
                         ("rq" + kNode + "/set_parametersRequest").c_str(), nullptr, nullptr);
    const dds_entity_t writer = dds_create_writer(raw.participant(), topic, qos, nullptr);
    dds_delete_qos(qos);
    return writer;
  }();
  ASSERT_GT(raw_writer, 0);
  ASSERT_TRUE(test::eventually(10.0, [&] {
    dds_publication_matched_status_t s{};
    dds_get_publication_matched_status(raw_writer, &s);
    return s.current_count > 0;
  }));
  const auto send = [&](std::vector<uint8_t> payload) {
    // payload[0..3] is replaced by the count of the bytes after it.
    payload.resize(std::max<std::size_t>(payload.size(), 4));
    peer_Raw sample{};
    std::vector<uint8_t> rest(payload.begin() + 4, payload.end());
    point(sample.bytes, rest.data(), rest.size());
    return dds_write(raw_writer, &sample) >= 0;
  };
  const std::vector<uint8_t> good = good_set_request(650.0);
  std::mt19937_64 random(20261127);
  int malformed = 0;
  for (std::size_t k = 4; k < good.size(); ++k) malformed += send({good.begin(), good.begin() + k});
  for (int i = 0; i < 2000; ++i) {
    std::vector<uint8_t> bytes(4 + random() % 300);
    for (uint8_t& b : bytes) b = static_cast<uint8_t>(random());
    malformed += send(bytes);
  }
  for (int i = 0; i < 2000; ++i) {
    std::vector<uint8_t> bytes = good;
    for (int j = 0; j < 3; ++j)
      bytes[4 + random() % (bytes.size() - 4)] = static_cast<uint8_t>(random());
    malformed += send(bytes);
  }

  // The good request among them was applied, after every truncation and mutation of it was
  // refused; a get waits for the raw requests to be taken (the same thread answers both).
  Peer peer(0x5eed000000000003ull);
  Services services(peer);
  ASSERT_TRUE(services.matched(10.0));
  ASSERT_TRUE(send(good));
  ++malformed;
  ASSERT_TRUE(test::eventually(5.0, [&] {
    const auto v = services.get_values({"stiffness.translation"});
    return v && v->size() == 1u && (*v)[0].numbers == std::vector<double>{650, 650, 650};
  }));

  // Hostile but well-formed requests from the independent client: unknown, empty and huge
  // names, type codes that are none of ROS 2's, NaN and infinity, integers where doubles are
  // expected, a parameter given twice, many parameters at once.
  int hostile = 0, refused = 0;
  const auto try_set = [&](std::vector<Parameter> parameters, bool atomically) {
    const auto result = services.set_values(std::move(parameters), atomically);
    ++hostile;
    EXPECT_TRUE(result.answered);
    for (const auto& [ok, reason] : result.results) {
      if (!ok) {
        ++refused;
        EXPECT_FALSE(reason.empty());
      }
    }
  };
  const double nan = std::nan(""), inf = HUGE_VAL;
  for (const bool atomically : {false, true}) {
    try_set({Parameter::number("", 1.0)}, atomically);
    try_set({Parameter::number(std::string(100000, 'x'), 1.0)}, atomically);
    try_set({Parameter::number("stiffness.translation", nan)}, atomically);
    try_set({Parameter::numbers_of("stiffness.translation", {inf, 1, 1})}, atomically);
    try_set({Parameter::numbers_of("stiffness.translation", std::vector<double>(10000, 1.0))},
            atomically);
    try_set({Parameter::string_of("stiffness.translation", "500")}, atomically);
    try_set({Parameter::number("stiffness", 500)}, atomically);
    try_set({Parameter::number("stiffness.translation", 500),
             Parameter::number("stiffness.translation", 600)},
            atomically);
    Parameter wrong_type = Parameter::number("stiffness.translation", 500);
    wrong_type.value.type = 200;
    try_set({wrong_type}, atomically);
    Parameter not_set = Parameter::number("stiffness.translation", 500);
    not_set.value.type = 0;
    try_set({not_set}, atomically);
    std::vector<Parameter> many;
    for (int i = 0; i < 1000; ++i)
      many.push_back(Parameter::number("no.such." + std::to_string(i), i));
    try_set(std::move(many), atomically);
  }
  std::vector<std::string> names(20000, "stiffness.translation");
  names.push_back(std::string(50000, 'y'));
  const auto big = services.get_values(names);
  ++hostile;
  ASSERT_TRUE(big);
  EXPECT_TRUE(big->empty());  // one unknown name: no values

  // The node still runs its controller and answers a good request, whose effect holds.
  EXPECT_TRUE(node.running()) << node.log();
  EXPECT_TRUE(state.wait(2.0, [](const ArmState& s) { return s.status == "ok"; }));
  const int before = state.count();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  state.poll();
  EXPECT_GT(state.count(), before) << "full_state stopped";
  // Of the hostile requests only set_parameters' pair of valid values is accepted, one after the
  // other (rclcpp sets each on its own; set_parameters_atomically refuses the pair as given
  // twice): the last, 600, is in force.
  auto values = services.get_values({"stiffness.translation"});
  ASSERT_TRUE(values && values->size() == 1u);
  EXPECT_EQ((*values)[0].numbers, (std::vector<double>{600, 600, 600}));
  const auto set = services.set_values({Parameter::number("stiffness.translation", 640.0)});
  ASSERT_TRUE(set.answered && set.results.size() == 1u && set.results[0].first);
  values = services.get_values({"stiffness.translation"});
  ASSERT_TRUE(values && values->size() == 1u);
  EXPECT_EQ((*values)[0].numbers, (std::vector<double>{640, 640, 640}));
  // The control thread's timing is reported, not asserted (this machine's 2 cores are shared):
  // the services' thread is its only competitor here.
  std::printf(
      "fuzz: %d malformed requests, %d hostile requests (%d refused parameters); control "
      "period since start p50 %.1f us, p99 %.1f us, %llu overruns\n",
      malformed, hostile, refused, state.value().period_p50_us, state.value().period_p99_us,
      static_cast<unsigned long long>(state.value().overruns));
  EXPECT_EQ(malformed, static_cast<int>(good.size() - 4) + 4001);
}

// Issue 41, what was left: 40 stiffnesses sent on the topic gave 0 parameter events. A change of
// a value that is also a parameter, from any channel, appears on /parameter_events (within the
// services' 50 ms poll) with the value in force, which get_parameters then returns. Each command
// waits for its event before the next is sent: every one is seen.
TEST(ParameterServices, TopicCommandsAppearOnParameterEvents) {
  test::use_private_domain();
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  StateReader state(node_participant(), "rt" + kNode + "/full_state", &copy_state);
  Peer peer(0x5eed000000000012ull);
  Services services(peer);
  Events events(peer);
  ASSERT_TRUE(state.wait(15.0, [](const ArmState& s) { return s.status == "ok"; })) << node.log();
  ASSERT_TRUE(services.matched(10.0));
  ASSERT_TRUE(events.matched(5.0));
  using cartesian_impedance_ros2::Writer;
  const auto& participant = node_participant();
  Writer<cartesian_impedance_ros2::WrenchStamped> stiffness(
      participant, "rt" + kNode + "/set_cartesian_stiffness", cartesian_impedance_ros2::TopicQos{});
  Writer<cartesian_impedance_ros2::WrenchStamped> wrench(
      participant, "rt" + kNode + "/set_cartesian_wrench", cartesian_impedance_ros2::TopicQos{});
  Writer<cartesian_impedance_ros2::WrenchMessage> damping(
      participant, "rt" + kNode + "/set_damping_factors", cartesian_impedance_ros2::TopicQos{});
  ASSERT_TRUE(test::eventually(5.0, [&] {
    return stiffness.matched() > 0 && wrench.matched() > 0 && damping.matched() > 0;
  }));

  std::size_t seen = events.poll().size();
  // The next event that changes `name`, its value (nullopt within 2 s: none).
  const auto next_change = [&](const std::string& name) -> std::optional<Value> {
    std::optional<Value> found;
    test::eventually(2.0, [&] {
      const auto& all = events.poll();
      for (; seen < all.size() && !found; ++seen) {
        for (const auto& [changed, value] : all[seen].changed) {
          if (changed == name) found = value;
        }
      }
      return found.has_value();
    });
    return found;
  };
  cartesian_impedance_ros2::WrenchStamped k{};
  k.header.frame_id = const_cast<char*>("");
  k.wrench.torque = {30, 30, 30};
  int reported = 0;
  for (int i = 0; i < 20; ++i) {
    const double value = 300.0 + 10.0 * i;
    k.wrench.force = {value, value, value + 1.0};
    ASSERT_TRUE(stiffness.write(k));
    const auto event = next_change("stiffness.translation");
    if (event && event->numbers == std::vector<double>{value, value, value + 1.0}) ++reported;
  }
  EXPECT_EQ(reported, 20) << "of 20 stiffnesses sent on the topic, reported on /parameter_events";
  auto values = services.get_values({"stiffness.translation", "stiffness.rotation"});
  ASSERT_TRUE(values && values->size() == 2u);
  EXPECT_EQ((*values)[0].numbers, (std::vector<double>{490, 490, 491}));
  EXPECT_EQ((*values)[1].numbers, (std::vector<double>{30, 30, 30}));

  cartesian_impedance_ros2::WrenchMessage zeta{};
  zeta.force = {0.8, 0.8, 0.8};
  zeta.torque = {0.9, 0.9, 0.9};
  ASSERT_TRUE(damping.write(zeta));
  auto event = next_change("damping_ratio.translation");
  ASSERT_TRUE(event);
  EXPECT_EQ(event->numbers, (std::vector<double>{0.8, 0.8, 0.8}));
  cartesian_impedance_ros2::WrenchStamped f{};
  f.header.frame_id = const_cast<char*>("");
  f.wrench.force = {0, 0, -2};
  ASSERT_TRUE(wrench.write(f));
  event = next_change("wrench.force");
  ASSERT_TRUE(event);
  EXPECT_EQ(event->numbers, (std::vector<double>{0, 0, -2}));

  // A set is reported once, by its own event: no second event for it before the next topic
  // change's.
  const auto set = services.set_values({Parameter::number("filter.pose.time", 0.3)});
  ASSERT_TRUE(set.answered && set.results.size() == 1u && set.results[0].first);
  ASSERT_TRUE(next_change("filter.pose.time"));
  k.wrench.force = {600, 600, 600};
  ASSERT_TRUE(stiffness.write(k));
  const std::size_t from = seen;
  ASSERT_TRUE(next_change("stiffness.translation"));
  const auto& all = events.poll();
  for (std::size_t i = from; i < seen; ++i) {
    for (const auto& [name, value] : all[i].changed) EXPECT_NE(name, "filter.pose.time");
  }
  EXPECT_TRUE(node.running()) << node.log();
}

// ---- (d) closed loop: a set over the service changes what the arm does ------------------------

// Tolerances: the Panda model's joint friction holds the flange within about 1.1 mm of the spring's
// rest at 500 N/m (node_test.cpp), scaling with 1/K: 1.5 mm at 500 N/m, 0.75 mm at 1000 N/m.
TEST(ParameterServices, StiffnessSetOverTheServiceChangesTheArmsResponse) {
  test::use_private_domain();
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  StateReader state(node_participant(), "rt" + kNode + "/full_state", &copy_state);
  cartesian_impedance_ros2::Writer<cartesian_impedance_ros2::WrenchStamped> wrench(
      node_participant(), "rt" + kNode + "/set_cartesian_wrench",
      cartesian_impedance_ros2::TopicQos{});
  Peer peer(0x5eed000000000004ull);
  Services services(peer);
  ASSERT_TRUE(state.wait(15.0, [](const ArmState& s) { return s.status == "ok"; })) << node.log();
  ASSERT_TRUE(services.matched(10.0));
  ASSERT_TRUE(test::eventually(5.0, [&] { return wrench.matched() > 0; }));
  const auto settle = [&](double seconds) {
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    state.poll();
    return state.value();
  };
  const auto k0 = services.get_values({"stiffness.translation"});
  ASSERT_TRUE(k0 && k0->size() == 1u);
  const double k = (*k0)[0].numbers[2];
  ASSERT_EQ(k, 500.0);  // config/panda.yaml; the tolerances above are for it
  const ArmState start = settle(0.5);

  // 5 N down: 10 mm at 500 N/m (from the reference, which stays where the controller started).
  cartesian_impedance_ros2::WrenchStamped push{};
  push.header.frame_id = const_cast<char*>("");
  push.wrench.force.z = -5.0;
  ASSERT_TRUE(wrench.write(push));
  const double soft = settle(3.0).position.z() - start.position.z();
  EXPECT_NEAR(soft, -5.0 / k, 1.5e-3);

  // Twice the stiffness over set_parameters, then the same push: half the displacement. The
  // push is released first: raising the stiffness under a 10 mm error would store
  // 1/2 dK e^2 = 25 mJ in the spring, more than the energy tank holds (5 mJ), and the change
  // would wait for the damping to refill it.
  push.wrench.force.z = 0.0;
  ASSERT_TRUE(wrench.write(push));
  settle(3.0);
  auto set = services.set_values({Parameter::number("stiffness.translation", 2 * k)});
  ASSERT_TRUE(set.answered && set.results.size() == 1u);
  ASSERT_TRUE(set.results[0].first) << set.results[0].second;
  settle(1.0);
  push.wrench.force.z = -5.0;
  ASSERT_TRUE(wrench.write(push));
  const ArmState stiff_state = settle(3.0);
  const double stiff = stiff_state.position.z() - start.position.z();
  EXPECT_NEAR(stiff, -5.0 / (2 * k), 0.75e-3);
  EXPECT_EQ(stiff_state.stiffness_x, 2 * k);

  // A refused set changes nothing: the stiffness in force and the arm stay.
  set = services.set_values({Parameter::number("stiffness.translation", -100.0)});
  ASSERT_TRUE(set.answered && set.results.size() == 1u);
  EXPECT_FALSE(set.results[0].first);
  std::printf("refused: %s\n", set.results[0].second.c_str());
  const ArmState after = settle(1.5);
  EXPECT_EQ(after.stiffness_x, 2 * k);
  EXPECT_NEAR(after.position.z(), stiff_state.position.z(), 0.3e-3);
  const auto k1 = services.get_values({"stiffness.translation"});
  ASSERT_TRUE(k1 && k1->size() == 1u);
  EXPECT_EQ((*k1)[0].numbers, (std::vector<double>{2 * k, 2 * k, 2 * k}));
  std::printf("closed loop: 5 N push moves the flange %.3f mm at %g N/m, %.3f mm at %g N/m\n",
              soft * 1e3, k, stiff * 1e3, 2 * k);
}

}  // namespace
}  // namespace parameter_services_test
