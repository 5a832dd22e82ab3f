// ros2_fastdds_peer: a stand-in for a stock ROS 2 node on Fast DDS (rmw_fastrtps), for tests of
// cartesian_impedance_ros2. Prints one JSON object per line on stdout; exits 0 on success, 1 on
// failure or timeout, 2 on bad usage.
//
//   pose  [--ns FQ] [--x X --y Y --z Z | --dx D --dy D --dz D] [--qx --qy --qz --qw]
//         [--frame-id F] [--tolerance M] [--settle S] [--timeout S] [--match-wait S]
//         [--wrong-type-name | --xcdr2]
//   echo  TOPIC TYPE [--count N] [--timeout S]
//   pub   TOPIC TYPE [field=value ...] [--count N] [--rate HZ] [--timeout S]
//   fuzz  TOPIC TYPE [field=value ...] [--seed S] [--count N] [--rate HZ] [--timeout S]
//
// pose publishes on <ns>/reference_pose and follows <ns>/controller_state until the current pose
// stays within the tolerance for --settle seconds. --wrong-type-name registers the pose type as
// PoseStampd_; --xcdr2 offers XCDR2 and writes PLAIN_CDR2 samples, but Fast DDS 2.9 does not
// announce the representation in discovery, so that writer matches XCDR1 readers all the same
// (ros2_cyclone_pose_writer is the XCDR2 writer that does announce it).
// fuzz writes --count malformed variants (peer_fuzz.hpp) of the sample given by the fields.
// TOPIC is a fully-qualified ROS name, TYPE a ROS type name (sensor_msgs/msg/JointState).
// Fields per type: peer_messages.cpp. Environment: ROS_DOMAIN_ID, FASTRTPS_DEFAULT_PROFILES_FILE.

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <set>
#include <stdexcept>
#include <thread>

#include "fastdds_messagesPubSubTypes.h"
#include "peer_dds.hpp"
#include "peer_fuzz.hpp"
#include "peer_messages.hpp"

namespace fastdds_peer {
namespace {

namespace dds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;
using ReturnCode_t = eprosima::fastrtps::types::ReturnCode_t;

void emit(const std::string& json) {
  std::cout << json << std::endl;
}

std::string event(const std::string& name, const std::string& fields = "") {
  return "{\"event\":" + json_string(name) + (fields.empty() ? "" : "," + fields) + "}";
}

struct UsageError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// argv after the subcommand: --flag, --option value, positional.
struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> options;
  std::set<std::string> flags;

  double number(const std::string& key, double fallback) const {
    const auto found = options.find(key);
    if (found == options.end()) {
      return fallback;
    }
    char* end = nullptr;
    const double value = std::strtod(found->second.c_str(), &end);
    if (found->second.empty() || *end != '\0' || !std::isfinite(value)) {
      throw UsageError("--" + key + " needs a number, got " + found->second);
    }
    return value;
  }
  std::string text(const std::string& key, const std::string& fallback) const {
    const auto found = options.find(key);
    return found == options.end() ? fallback : found->second;
  }
};

Args parse(int argc, char** argv, const std::set<std::string>& flag_names) {
  Args args;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--", 0) != 0) {
      args.positional.push_back(arg);
    } else if (flag_names.count(arg.substr(2))) {
      args.flags.insert(arg.substr(2));
    } else if (i + 1 < argc) {
      args.options[arg.substr(2)] = argv[++i];
    } else {
      throw UsageError(arg + " needs a value");
    }
  }
  return args;
}

Clock::time_point after(double seconds) {
  return Clock::now() +
         std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

/// Seconds left until `deadline`, at least 0.
double left(Clock::time_point deadline) {
  return std::max(0.0, std::chrono::duration<double>(deadline - Clock::now()).count());
}

/// Takes the next valid sample into `data`, waiting up to `timeout` seconds.
bool take(dds::DataReader* reader, void* data, double timeout) {
  dds::SampleInfo info;
  const auto deadline = after(timeout);
  for (;;) {
    while (reader->take_next_sample(data, &info) == ReturnCode_t::RETCODE_OK) {
      if (info.valid_data) {
        return true;
      }
    }
    const double wait = left(deadline);
    if (wait <= 0) {
      return false;
    }
    reader->wait_for_unread_message(eprosima::fastrtps::Duration_t(std::min(wait, 0.1)));
  }
}

// ---- pose ---------------------------------------------------------------------------------------

int pose(const Args& args) {
  namespace cic = cartesian_impedance_controller::msg::dds_;
  namespace gm = geometry_msgs::msg::dds_;
  const std::string ns = args.text("ns", "/cartesian_impedance_controller");
  const bool wrong_type_name = args.flags.count("wrong-type-name") > 0;
  const bool xcdr2 = args.flags.count("xcdr2") > 0;
  const bool negative = wrong_type_name || xcdr2;
  if (wrong_type_name && xcdr2) {
    throw UsageError("--wrong-type-name and --xcdr2 break one rule each: use one");
  }
  const double tolerance = args.number("tolerance", 0.005);
  const double settle = args.number("settle", 0.5);
  const auto deadline = after(args.number("timeout", 20));

  Peer peer;
  const TypeNames& state_names = type_names("cartesian_impedance_controller/msg/ControllerState");
  dds::DataReader* states = peer.reader(
      ns + "/controller_state", new cic::ControllerState_PubSubType(), state_names.type_hash);
  const TypeNames& pose_names = type_names("geometry_msgs/msg/PoseStamped");
  dds::TopicDataType* pose_type = nullptr;
  if (xcdr2) {
    pose_type = new RawType(pose_names.dds_name);
  } else {
    pose_type = new gm::PoseStamped_PubSubType();
    if (wrong_type_name) {
      pose_type->setName("geometry_msgs::msg::dds_::PoseStampd_");
    }
  }
  const std::string mode = xcdr2 ? "xcdr2" : wrong_type_name ? "wrong_type_name" : "valid";
  dds::DataWriter* writer = peer.writer(ns + "/reference_pose", pose_type, pose_names.type_hash,
                                        xcdr2 ? Representation::xcdr2 : Representation::xcdr1);
  emit(event("started", "\"mode\":" + json_string(mode) +
                            ",\"domain\":" + std::to_string(peer.domain()) +
                            ",\"writer_type\":" + json_string(pose_type->getName())));

  cic::ControllerState_ state;
  if (!take(states, &state, left(deadline))) {
    emit(event("error", "\"error\":\"no controller_state received\""));
    return 1;
  }
  const auto position = [](const cic::ControllerState_& s) {
    const auto& p = s.current_pose().position();
    return std::array<double, 3>{p.x(), p.y(), p.z()};
  };
  const std::array<double, 3> start = position(state);
  const auto& q0 = state.current_pose().orientation();
  emit(event("start", "\"position\":" + json_numbers({start[0], start[1], start[2]}) +
                          ",\"orientation\":" + json_numbers({q0.x(), q0.y(), q0.z(), q0.w()})));
  const std::array<double, 3> target = {args.number("x", start[0] + args.number("dx", 0)),
                                        args.number("y", start[1] + args.number("dy", 0)),
                                        args.number("z", start[2] + args.number("dz", 0))};
  const std::array<double, 7> pose = {target[0],
                                      target[1],
                                      target[2],
                                      args.number("qx", q0.x()),
                                      args.number("qy", q0.y()),
                                      args.number("qz", q0.z()),
                                      args.number("qw", q0.w())};
  const std::string frame_id = args.text("frame-id", "");

  // A valid writer waits for the node's reader. A broken one must never match: wait a while
  // (the states prove that discovery between the two participants is done) and report.
  int matches = 0;
  if (negative) {
    const auto until = after(args.number("match-wait", 2));
    while (left(until) > 0 && take(states, &state, left(until))) {
    }
    matches = matched(writer);
  } else {
    matches = wait_matched(writer, left(deadline));
  }
  emit(event("matched", "\"count\":" + std::to_string(matches)));
  if (!negative && matches == 0) {
    emit(event("error", "\"error\":\"reference_pose writer did not match\""));
    return 1;
  }

  gm::PoseStamped_ sample;
  sample.header().frame_id(frame_id);
  auto& p = sample.pose();
  p.position().x(pose[0]), p.position().y(pose[1]), p.position().z(pose[2]);
  p.orientation().x(pose[3]), p.orientation().y(pose[4]);
  p.orientation().z(pose[5]), p.orientation().w(pose[6]);
  const auto publish = [&] {
    const double now = wall_time();
    if (xcdr2) {
      Bytes bytes = xcdr2_pose_stamped(now, frame_id, pose);
      return writer->write(&bytes);
    }
    sample.header().stamp().sec(static_cast<std::int32_t>(now));
    sample.header().stamp().nanosec(static_cast<std::uint32_t>((now - std::floor(now)) * 1e9));
    return writer->write(&sample);
  };
  emit(event("publish", "\"target\":" + json_numbers({pose.begin(), pose.end()})));

  double max_deviation = 0;
  double error = INFINITY;
  auto within_since = Clock::time_point::max();
  auto next_publish = Clock::now();
  int published = 0;
  while (left(deadline) > 0) {
    // A few quick copies, then one a second: volatile and reliable, so once is enough for a
    // matched reader; the repeats give a wrongly matching one every chance to show.
    if (Clock::now() >= next_publish) {
      publish();
      ++published;
      next_publish += std::chrono::milliseconds(published < 3 ? 100 : 1000);
    }
    if (!take(states, &state, std::min(0.1, left(deadline)))) {
      continue;
    }
    const auto x = position(state);
    const auto& r = state.reference_pose().position();
    error = std::hypot(x[0] - target[0], x[1] - target[1], x[2] - target[2]);
    max_deviation =
        std::max(max_deviation, std::hypot(x[0] - start[0], x[1] - start[1], x[2] - start[2]));
    emit(event("state", "\"position\":" + json_numbers({x[0], x[1], x[2]}) +
                            ",\"reference\":" + json_numbers({r.x(), r.y(), r.z()}) +
                            ",\"error\":" + json_number(error)));
    if (negative || error > tolerance) {
      within_since = Clock::time_point::max();
    } else if (within_since == Clock::time_point::max()) {
      within_since = Clock::now();
    } else if (std::chrono::duration<double>(Clock::now() - within_since).count() >= settle) {
      break;
    }
  }
  const bool converged = !negative && error <= tolerance && left(deadline) > 0;
  emit(event("result", std::string("\"converged\":") + (converged ? "true" : "false") +
                           ",\"error\":" + json_number(error) +
                           ",\"max_deviation_from_start\":" + json_number(max_deviation) +
                           ",\"matched\":" + std::to_string(matched(writer)) +
                           ",\"published\":" + std::to_string(published)));
  return converged ? 0 : 1;
}

// ---- echo, pub, fuzz ----------------------------------------------------------------------------

int echo(const Args& args) {
  if (args.positional.size() != 2) {
    throw UsageError("echo TOPIC TYPE");
  }
  const std::string& topic = args.positional[0];
  auto message = make_message(args.positional[1]);
  const long count = static_cast<long>(args.number("count", 1));
  const auto deadline = after(args.number("timeout", 10));
  Peer peer;
  dds::DataReader* reader =
      peer.reader(topic, message->new_type(), type_names(message->ros_type()).type_hash);
  long received = 0;
  while (received < count && take(reader, message->data(), left(deadline))) {
    ++received;
    emit(event("sample", "\"topic\":" + json_string(topic) + ",\"data\":" + message->json()));
  }
  emit(event("done", "\"count\":" + std::to_string(received) +
                         ",\"matched\":" + std::to_string(matched(reader))));
  return received >= count ? 0 : 1;
}

/// Writes `count` samples made by `make` at `rate` Hz once a reader matched; waits for their
/// acknowledgement so that the samples are delivered before the process goes.
template <typename Make>
int write_all(const std::string& topic, dds::DataWriter* writer, const Args& args, Make make,
              std::string fields) {
  const long count = static_cast<long>(args.number("count", 1));
  const double rate = args.number("rate", 100);
  const int matches = wait_matched(writer, args.number("timeout", 10));
  if (matches == 0) {
    emit(event("error", "\"error\":\"no reader matched on " + topic + "\""));
    return 1;
  }
  long failed = 0;
  auto next = Clock::now();
  for (long i = 0; i < count; ++i) {
    failed += make(i) ? 0 : 1;
    next += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1 / rate));
    std::this_thread::sleep_until(next);
  }
  const bool acknowledged = writer->wait_for_acknowledgments(
                                eprosima::fastrtps::Duration_t(5, 0)) == ReturnCode_t::RETCODE_OK;
  emit(event("published", "\"topic\":" + json_string(topic) + ",\"count\":" +
                              std::to_string(count) + ",\"failed\":" + std::to_string(failed) +
                              ",\"matched\":" + std::to_string(matched(writer)) +
                              ",\"acknowledged\":" + (acknowledged ? "true" : "false") + fields));
  return failed == 0 ? 0 : 1;
}

int pub(const Args& args) {
  if (args.positional.size() < 2) {
    throw UsageError("pub TOPIC TYPE [field=value ...]");
  }
  const std::string& topic = args.positional[0];
  auto message = make_message(args.positional[1]);
  assign_all(*message, {args.positional.begin() + 2, args.positional.end()});
  Peer peer;
  dds::DataWriter* writer =
      peer.writer(topic, message->new_type(), type_names(message->ros_type()).type_hash);
  return write_all(
      topic, writer, args,
      [&](long) {
        message->stamp(wall_time());
        return writer->write(message->data());
      },
      ",\"sample\":" + message->json());
}

int fuzz(const Args& args) {
  if (args.positional.size() < 2) {
    throw UsageError("fuzz TOPIC TYPE [field=value ...]");
  }
  const std::string& topic = args.positional[0];
  auto message = make_message(args.positional[1]);
  assign_all(*message, {args.positional.begin() + 2, args.positional.end()});
  message->stamp(wall_time());
  const auto seed = static_cast<std::uint64_t>(args.number("seed", 1));
  Fuzzer fuzzer(serialize(*message), seed);
  const TypeNames& names = type_names(message->ros_type());
  Peer peer;
  dds::DataWriter* writer = peer.writer(topic, new RawType(names.dds_name), names.type_hash);
  std::array<long, static_cast<std::size_t>(Mutation::count_)> kinds{};
  const int status = write_all(
      topic, writer, args,
      [&](long) {
        Mutation kind;
        Bytes bytes = fuzzer.next(&kind);
        ++kinds[static_cast<std::size_t>(kind)];
        return writer->write(&bytes);
      },
      ",\"seed\":" + std::to_string(seed));
  std::string counts;
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    counts += (i ? ",\"" : "\"") + std::string(name(static_cast<Mutation>(i))) +
              "\":" + std::to_string(kinds[i]);
  }
  emit(event("mutations", counts));
  return status;
}

}  // namespace
}  // namespace fastdds_peer

int main(int argc, char** argv) {
  using namespace fastdds_peer;
  const std::string command = argc > 1 ? argv[1] : "";
  try {
    if (command == "pose") {
      return pose(parse(argc, argv, {"wrong-type-name", "xcdr2"}));
    }
    if (command == "echo") {
      return echo(parse(argc, argv, {}));
    }
    if (command == "pub") {
      return pub(parse(argc, argv, {}));
    }
    if (command == "fuzz") {
      return fuzz(parse(argc, argv, {}));
    }
    throw UsageError("subcommand pose, echo, pub or fuzz expected");
  } catch (const std::invalid_argument& e) {
    emit(event("error", "\"error\":" + json_string(e.what())));
    std::cerr << "ros2_fastdds_peer: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    emit(event("error", "\"error\":" + json_string(e.what())));
    std::cerr << "ros2_fastdds_peer: " << e.what() << "\n";
    return 1;
  }
}
