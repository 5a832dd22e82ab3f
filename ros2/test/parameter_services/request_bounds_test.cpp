// ROS 2's parameter services under requests meant to tie them up (issue 41, item 2), end to end
// over DDS from the independent client (peer.hpp): requests beyond the bounds every request is
// held to, refused before any work and named without being echoed; a storm from two clients,
// and what it does to the control thread; a client that reads no replies.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
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

std::size_t request_limits_items() {
  return static_cast<std::size_t>(cartesian_impedance_ros2::request_limits::kItems);
}

// Issue 2: one 8 MB parameter name took the services ~5 s of CPU per MB (the decoder's
// suggestions for an unknown name), a get behind it waited as long, the reason quoted the name
// twice and the node's memory grew by 95 MB. Every request is now held to request_limits before
// any work: refused at once, the reason naming what and how long and never quoting it whole.
// Before, the 1 MiB name alone was answered after about 5 s (past the client's 5 s wait) with a
// 2 MiB reason.
TEST(ParameterServices, OversizedRequestsAreRefusedBeforeAnyWork) {
  test::use_private_domain();
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  StateReader state(node_participant(), "rt" + kNode + "/full_state", &copy_state);
  ASSERT_TRUE(state.wait(15.0, [](const ArmState& s) { return s.status == "ok"; })) << node.log();
  Peer peer(0x5eed000000000011ull);
  Services services(peer);
  ASSERT_TRUE(services.matched(10.0));
  const auto seconds_since = [](test::Clock::time_point start) {
    return std::chrono::duration<double>(test::Clock::now() - start).count();
  };
  const auto refused_with = [&](const Services::Results& result, std::size_t count,
                                const std::string& fault) {
    ASSERT_TRUE(result.answered);
    ASSERT_EQ(result.results.size(), count);
    for (const auto& [ok, reason] : result.results) {
      EXPECT_FALSE(ok);
      EXPECT_NE(reason.find(fault), std::string::npos) << reason.substr(0, 400);
      EXPECT_NE(reason.find("nothing was changed"), std::string::npos) << reason.substr(0, 400);
      // Named, not echoed: the fault and the first 32 characters.
      EXPECT_LT(reason.size(), 400u);
    }
  };

  // A 1 MiB name, on each set service; the answer must not wait on the name's length (the
  // refusal is a few microseconds of work; 1 s leaves room for this shared machine).
  const std::string huge(1 << 20, 'x');
  for (const bool atomically : {false, true}) {
    const auto start = test::Clock::now();
    const auto result = services.set_values({Parameter::number(huge, 1.0)}, atomically);
    EXPECT_LT(seconds_since(start), 1.0);
    refused_with(result, 1,
                 "parameters[0].name of 1048576 characters (beginning "
                 "'xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx...') is longer than 128");
  }
  // One oversized parameter refuses the request's every parameter (one result each).
  refused_with(
      services.set_values({Parameter::number("filter.pose.time", 0.3),
                           Parameter::string_of("stiffness.frame", std::string(5000, 'b'))}),
      2, "parameters[1].value.string_value of 5000 characters");
  refused_with(
      services.set_values(
          {Parameter::numbers_of("stiffness.translation", std::vector<double>(2000, 500.0))}, true),
      1, "parameters[0].value.double_array_value elements: 2000, more than 1024");
  // Too many parameters: one result, not one per parameter claimed.
  std::vector<Parameter> many;
  for (int i = 0; i < 300; ++i) many.push_back(Parameter::number("filter.pose.time", 0.3));
  refused_with(services.set_values(many), 1, "parameters: 300, more than 256");
  // Reads: no values, as rclcpp answers a request it cannot answer whole.
  auto values = services.get_values(std::vector<std::string>(257, "filter.pose.time"));
  ASSERT_TRUE(values);
  EXPECT_TRUE(values->empty());
  values = services.get_values({"filter.pose.time", std::string(129, 'n')});
  ASSERT_TRUE(values);
  EXPECT_TRUE(values->empty());
  // Logged, once a second per service (the first of the two).
  EXPECT_NE(node.log().find("get_parameters refused: names: 257, more than 256"), std::string::npos)
      << node.log();

  // The node's memory after eight 4 MiB names: Cyclone must receive each, but nothing of them
  // stays (before, glibc's mmap threshold rose to the block freed and later ones stayed on the
  // heap: 12 MB more here, 95 MB in the issue). Measured since: 0 on an idle machine, up to 4.6 MB
  // beside other tests (Cyclone's receive buffers in use while it lags); less than two
  // requests' size may remain.
  const long before_kb = node.resident_kb();
  const std::string name_4mb(4 << 20, 'z');
  for (int i = 0; i < 8; ++i) {
    const auto start = test::Clock::now();
    const auto result = services.set_values({Parameter::number(name_4mb, 1.0)});
    EXPECT_LT(seconds_since(start), 1.0);
    refused_with(result, 1, "parameters[0].name of 4194304 characters");
  }
  const long after_kb = node.resident_kb();
  std::printf("node memory: %ld kB before eight 4 MiB names, %ld kB after\n", before_kb, after_kb);
  EXPECT_LT(after_kb - before_kb, 8192L);

  // Still answering, at once, and the arm still under control.
  const auto start = test::Clock::now();
  const auto set = services.set_values({Parameter::number("filter.pose.time", 0.3)});
  ASSERT_TRUE(set.answered && set.results.size() == 1u && set.results[0].first)
      << (set.results.empty() ? "" : set.results[0].second);
  values = services.get_values({"filter.pose.time"});
  EXPECT_LT(seconds_since(start), 1.0);
  ASSERT_TRUE(values && values->size() == 1u);
  EXPECT_EQ((*values)[0].number, 0.3);
  EXPECT_TRUE(node.running()) << node.log();
  EXPECT_TRUE(state.wait(2.0, [](const ArmState& s) { return s.status == "ok"; }));
}

// A client that announces itself (clientid, as rmw_cyclonedds_cpp's clients do) but has no reply
// reader: the services wait up to 100 ms for its reader before each reply, as rmw_cyclonedds_cpp
// does. Before, they waited so for every one of its requests, and a stream of them on one service
// kept every other client waiting (the services' thread drained one service before the next): a
// get from another client was not answered within 5 s. Now such a client is waited for once per
// 10 s, and each service is served at most 16 requests per round.
TEST(ParameterServices, AClientThatReadsNoRepliesDelaysNoOther) {
  test::use_private_domain();
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  StateReader state(node_participant(), "rt" + kNode + "/full_state", &copy_state);
  ASSERT_TRUE(state.wait(15.0, [](const ArmState& s) { return s.status == "ok"; })) << node.log();
  Peer mute(0x5eed000000000031ull);
  const dds_entity_t writer = [&] {
    dds_qos_t* qos = mute.service_qos();
    const dds_entity_t topic = dds_create_topic(
        mute.participant(), mute.named(peer_NamesRequest_desc, request_type("DescribeParameters")),
        ("rq" + kNode + "/describe_parametersRequest").c_str(), nullptr, nullptr);
    const dds_entity_t w = dds_create_writer(mute.participant(), topic, qos, nullptr);
    dds_delete_qos(qos);
    return w;
  }();
  ASSERT_GT(writer, 0);
  ASSERT_TRUE(test::eventually(10.0, [&] {
    dds_publication_matched_status_t s{};
    dds_get_publication_matched_status(writer, &s);
    return s.current_count > 0;
  }));
  Peer peer(0x5eed000000000032ull);
  Services services(peer);
  ASSERT_TRUE(services.matched(10.0));

  std::atomic<bool> stop{false};
  std::atomic<int> written{0};
  std::thread stream([&] {
    std::string name = "filter.pose.time";
    char* names[] = {name.data()};
    for (std::int64_t sequence = 1; !stop; ++sequence) {
      peer_NamesRequest request{};
      request.header.client = mute.client_id();
      request.header.number = sequence;
      point(request.names, names, 1);
      if (dds_write(writer, &request) >= 0) ++written;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the stream is flowing
  double slowest = 0.0;
  bool all_answered = true;
  for (int i = 0; i < 5; ++i) {
    const auto start = test::Clock::now();
    const auto values = services.get_values({"filter.pose.time"});
    slowest = std::max(slowest, std::chrono::duration<double>(test::Clock::now() - start).count());
    all_answered = all_answered && values && values->size() == 1u;
  }
  stop = true;
  stream.join();
  std::printf("with %d requests from a client without a reply reader: slowest get %.3f s\n",
              written.load(), slowest);
  EXPECT_TRUE(all_answered);
  // One wait of 100 ms for the mute client, and a round of 16 of its requests: well under 1 s.
  EXPECT_LT(slowest, 1.0);
  EXPECT_TRUE(node.running()) << node.log();
}

// Issue 2's storm: two clients call the services back to back for 2 s with the costliest
// requests within request_limits (256 names to get and describe, sets of an unknown 128-character
// name, whose suggestions are the decoder's most expensive answer, and valid sets). Every request
// is answered and the last valid set is in force. The control thread's timing during the storm
// and in a quiet stretch as long before it is reported, not asserted (this machine's 2 cores are
// shared); the services' thread runs at nice 10, so that the scheduler prefers the control thread.
TEST(ParameterServices, ServiceStormIsAnsweredAndReported) {
  test::use_private_domain();
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  StateReader state(node_participant(), "rt" + kNode + "/full_state", &copy_state);
  ASSERT_TRUE(state.wait(15.0, [](const ArmState& s) { return s.status == "ok"; })) << node.log();
  const auto overruns_over = [&](double seconds) {
    state.poll();
    const std::uint64_t before = state.value().overruns;
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    EXPECT_TRUE(state.wait(1.0, [](const ArmState& s) { return s.status == "ok"; }));
    return state.value().overruns - before;
  };
  const std::uint64_t quiet = overruns_over(2.0);
  const double quiet_p99 = state.value().period_p99_us;

  std::atomic<bool> stop{false};
  std::atomic<int> answered{0}, unanswered{0};
  const auto client = [&](std::uint64_t id) {
    Peer peer(id);
    Services services(peer);
    if (!services.matched(10.0)) {
      ++unanswered;
      return;
    }
    const std::vector<std::string> names(request_limits_items(), "filter.pose.time");
    const std::string unknown(128, 'u');
    for (int i = 0; !stop; ++i) {
      bool ok = false;
      switch (i % 4) {
        case 0:
          ok = services.get_values(names).has_value();
          break;
        case 1:
          ok = services.describe_values(names).has_value();
          break;
        case 2:
          ok = services.set_values({Parameter::number(unknown, 1.0)}).answered;
          break;
        default:
          ok = services.set_values({Parameter::number("filter.pose.time", 0.3)}).answered;
      }
      ok ? ++answered : ++unanswered;
    }
  };
  state.poll();
  const std::uint64_t before = state.value().overruns;
  std::thread first(client, 0x5eed000000000021ull);
  std::thread second(client, 0x5eed000000000022ull);
  std::this_thread::sleep_for(std::chrono::seconds(2));
  stop = true;
  first.join();
  second.join();
  ASSERT_TRUE(state.wait(1.0, [](const ArmState& s) { return s.status == "ok"; }));
  const std::uint64_t storm = state.value().overruns - before;
  EXPECT_GT(answered.load(), 0);
  EXPECT_EQ(unanswered.load(), 0);
  EXPECT_TRUE(node.running()) << node.log();
  std::printf(
      "service storm: %d requests answered in 2 s by two clients; control thread overruns %llu "
      "in 2 s of storm, %llu in 2 s quiet; period p99 since start %.1f us after the quiet "
      "stretch, %.1f us after the storm\n",
      answered.load(), static_cast<unsigned long long>(storm),
      static_cast<unsigned long long>(quiet), quiet_p99, state.value().period_p99_us);
}

}  // namespace
}  // namespace parameter_services_test
