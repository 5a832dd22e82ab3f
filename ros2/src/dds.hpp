#pragma once
/// @file
/// The node's DDS entities with ROS 2's conventions, on Cyclone DDS's C API: a participant that
/// announces `enclave=/;`, and per topic a writer or reader of one generated message type that
/// announces its RIHS01 type hash (`typehash=RIHS01_...;`) and offers or requests XCDR1 only, the
/// representation both of ROS 2's DDS layers use (an XCDR2 peer does not match). Types are matched
/// by name alone: the generated descriptors carry no type information (idlc -t).

#include <dds/dds.h>

#include <cstdint>
#include <string>
#include <type_traits>

#include "ros2_messages.hpp"

namespace cartesian_impedance_ros2 {

/// QoS of one topic: ROS 2's default profile unless the parameters override it
/// (qos_overrides.<topic>.publisher|subscription.*).
struct TopicQos {
  bool reliable = true;          ///< reliable (else best effort)
  bool transient_local = false;  ///< transient local (else volatile)
  int depth = 10;                ///< keep last `depth` samples
};

/// A DDS entity handle deleted with its children when the owner goes.
class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t id) : id_(id) {}
  ~Entity();
  Entity(Entity&& other) noexcept : id_(other.id_) { other.id_ = 0; }
  Entity& operator=(Entity&& other) noexcept;
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;
  dds_entity_t get() const noexcept { return id_; }

 private:
  dds_entity_t id_ = 0;
};

/// @throws cartesian_impedance::Error naming `what` and DDS's reason if `result` is an error.
dds_entity_t check(dds_entity_t result, const std::string& what);

/// The domain participant: domain ROS_DOMAIN_ID (0 if unset), configured by CYCLONEDDS_URI as
/// Cyclone reads it.
class Participant {
 public:
  /// @throws cartesian_impedance::Error for an invalid ROS_DOMAIN_ID or if DDS cannot start.
  Participant();
  dds_entity_t get() const noexcept { return participant_.get(); }
  std::uint32_t domain() const noexcept { return domain_; }

 private:
  std::uint32_t domain_ = 0;
  Entity participant_;
};

/// The endpoint QoS of a topic: reliability, durability, history, XCDR1, typehash USER_DATA
/// (none if `type_hash` is null).
dds_qos_t* endpoint_qos(const TopicQos& qos, const char* type_hash);

/// A topic of `Message` (generated C type) named `dds_name` ("rt/..."), shared by its endpoints.
dds_entity_t find_or_create_topic(const Participant& participant,
                                  const dds_topic_descriptor_t* type, const std::string& dds_name);

template <typename Message>
class Writer {
 public:
  Writer() = default;
  /// @throws cartesian_impedance::Error naming the topic if DDS refuses it.
  Writer(const Participant& participant, const std::string& dds_name, const TopicQos& qos)
      : name_(dds_name) {
    const dds_entity_t topic =
        find_or_create_topic(participant, MessageType<Message>::descriptor(), dds_name);
    dds_qos_t* q = endpoint_qos(qos, MessageType<Message>::type_hash);
    const dds_entity_t writer = dds_create_writer(participant.get(), topic, q, nullptr);
    dds_delete_qos(q);
    writer_ = Entity(check(writer, "writer of " + dds_name));
  }

  /// False if DDS did not take it (logged by the caller).
  bool write(const Message& message) const { return dds_write(writer_.get(), &message) >= 0; }
  dds_entity_t get() const noexcept { return writer_.get(); }
  /// Readers currently matched.
  int matched() const;
  const std::string& name() const noexcept { return name_; }
  bool valid() const noexcept { return writer_.get() > 0; }

 private:
  std::string name_;
  Entity writer_;
};

template <typename Message>
class Reader {
 public:
  Reader() = default;
  /// @throws cartesian_impedance::Error naming the topic if DDS refuses it.
  Reader(const Participant& participant, const std::string& dds_name, const TopicQos& qos)
      : name_(dds_name) {
    const dds_entity_t topic =
        find_or_create_topic(participant, MessageType<Message>::descriptor(), dds_name);
    dds_qos_t* q = endpoint_qos(qos, MessageType<Message>::type_hash);
    const dds_entity_t reader = dds_create_reader(participant.get(), topic, q, nullptr);
    dds_delete_qos(q);
    reader_ = Entity(check(reader, "reader of " + dds_name));
  }

  /// Takes every sample waiting (valid data only) and calls `each(const Message&)` (or
  /// `each(const Message&, const dds_sample_info_t&)`, with the writer's source_timestamp) for
  /// each, on DDS's loaned memory. Returns how many were taken.
  template <typename Each>
  int take(Each&& each) {
    int taken = 0;
    for (;;) {
      void* samples[kBatch] = {};
      dds_sample_info_t infos[kBatch];
      const dds_return_t count = dds_take(reader_.get(), samples, infos, kBatch, kBatch);
      if (count <= 0) break;
      for (dds_return_t i = 0; i < count; ++i) {
        if (infos[i].valid_data) {
          const Message& message = *static_cast<const Message*>(samples[i]);
          if constexpr (std::is_invocable_v<Each, const Message&, const dds_sample_info_t&>) {
            each(message, infos[i]);
          } else {
            each(message);
          }
          ++taken;
        }
      }
      dds_return_loan(reader_.get(), samples, count);
      if (count < kBatch) break;
    }
    return taken;
  }

  dds_entity_t get() const noexcept { return reader_.get(); }
  const std::string& name() const noexcept { return name_; }

 private:
  static constexpr int kBatch = 16;
  std::string name_;
  Entity reader_;
};

int matched_readers(dds_entity_t writer);

template <typename Message>
int Writer<Message>::matched() const {
  return matched_readers(writer_.get());
}

}  // namespace cartesian_impedance_ros2
