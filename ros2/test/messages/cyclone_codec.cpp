#include "cyclone_codec.hpp"

#include <chrono>
#include <map>
#include <string>
#include <thread>

#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/ddsi_sertype.h>
#include <gtest/gtest.h>

namespace ros2_messages_test {
namespace {

// Cyclone 0.10.2 exports no accessor for a topic's sertype (dds_get_entity_sertype came later),
// but every serdata names its sertype: write one sample to a local reader, take it in serialized
// form (dds_takecdr) and keep serdata->type, which the topic keeps alive.
//
// The domain is private: loopback only, no multicast, and no participant index, so it neither
// discovers nor is discovered by the node tests that may run next to this one.
constexpr dds_domainid_t kDomain = 229;
constexpr const char* kConfig =
    "<General><Interfaces><NetworkInterface address=\"127.0.0.1\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General>"
    "<Discovery><ParticipantIndex>none</ParticipantIndex></Discovery>";

class Domain {
 public:
  Domain() {
    domain_ = dds_create_domain(kDomain, kConfig);
    if (domain_ > 0) participant_ = dds_create_participant(kDomain, nullptr, nullptr);
  }
  ~Domain() {
    if (domain_ > 0) dds_delete(domain_);
  }
  Domain(const Domain&) = delete;
  Domain& operator=(const Domain&) = delete;

  const ddsi_sertype* sertype(const dds_topic_descriptor_t* descriptor) {
    auto found = types_.find(descriptor);
    if (found != types_.end()) return found->second;
    const ddsi_sertype* type = make(descriptor);
    if (type != nullptr) types_[descriptor] = type;
    return type;
  }

 private:
  const ddsi_sertype* make(const dds_topic_descriptor_t* descriptor) {
    EXPECT_GT(participant_, 0) << "Cyclone refused the private domain: "
                               << dds_strretcode(participant_);
    if (participant_ <= 0) return nullptr;
    // The node's QoS: reliable, volatile, keep-last 10, XCDR1 only.
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
    const dds_data_representation_id_t xcdr1[] = {DDS_DATA_REPRESENTATION_XCDR1};
    dds_qset_data_representation(qos, 1, xcdr1);
    const std::string name = "rt/ros2_messages_test/t" + std::to_string(types_.size());
    const dds_entity_t topic =
        dds_create_topic(participant_, descriptor, name.c_str(), qos, nullptr);
    const dds_entity_t writer = dds_create_writer(participant_, topic, qos, nullptr);
    const dds_entity_t reader = dds_create_reader(participant_, topic, qos, nullptr);
    dds_delete_qos(qos);
    EXPECT_GT(topic, 0) << descriptor->m_typename << ": " << dds_strretcode(topic);
    EXPECT_GT(writer, 0) << descriptor->m_typename << ": " << dds_strretcode(writer);
    EXPECT_GT(reader, 0) << descriptor->m_typename << ": " << dds_strretcode(reader);
    if (topic <= 0 || writer <= 0 || reader <= 0) return nullptr;

    // Zero-initialized: empty sequences, and null strings, which Cyclone writes as "".
    std::vector<unsigned char> sample(descriptor->m_size, 0);
    const dds_return_t written = dds_write(writer, sample.data());
    EXPECT_EQ(written, DDS_RETCODE_OK) << dds_strretcode(written);
    ddsi_serdata* serdata = nullptr;
    dds_sample_info_t info;
    dds_return_t taken = 0;
    // Local delivery is synchronous in Cyclone; the loop only guards against a change of that.
    for (int attempt = 0; attempt < 100 && taken == 0; ++attempt) {
      taken = dds_takecdr(reader, &serdata, 1, &info, 0);
      if (taken == 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    EXPECT_EQ(taken, 1) << descriptor->m_typename << ": no sample taken";
    if (taken != 1) return nullptr;
    const ddsi_sertype* type = serdata->type;
    ddsi_serdata_unref(serdata);
    // Only the topic is needed from here on; it holds the sertype.
    dds_delete(reader);
    dds_delete(writer);
    return type;
  }

  dds_entity_t domain_ = 0;
  dds_entity_t participant_ = 0;
  std::map<const dds_topic_descriptor_t*, const ddsi_sertype*> types_;
};

Domain& domain() {
  static Domain instance;
  return instance;
}

}  // namespace

const ddsi_sertype* sertype_of(const dds_topic_descriptor_t* descriptor) {
  return domain().sertype(descriptor);
}

std::vector<uint8_t> cyclone_serialize(const ddsi_sertype* type, const void* sample) {
  ddsi_serdata* serdata = ddsi_serdata_from_sample(type, SDK_DATA, sample);
  if (serdata == nullptr) return {};
  std::vector<uint8_t> bytes(ddsi_serdata_size(serdata));
  ddsi_serdata_to_ser(serdata, 0, bytes.size(), bytes.data());
  ddsi_serdata_unref(serdata);
  return bytes;
}

bool cyclone_deserialize(const ddsi_sertype* type, const std::vector<uint8_t>& bytes,
                         void* sample) {
  // from_ser_iov copies the bytes into a serdata of its own before normalizing them in place, so
  // the const_cast never leads to a write into `bytes`.
  ddsrt_iovec_t iov;
  iov.iov_base = const_cast<uint8_t*>(bytes.data());
  iov.iov_len = bytes.size();
  ddsi_serdata* serdata = ddsi_serdata_from_ser_iov(type, SDK_DATA, 1, &iov, bytes.size());
  if (serdata == nullptr) return false;
  const bool decoded = ddsi_serdata_to_sample(serdata, sample, nullptr, nullptr);
  ddsi_serdata_unref(serdata);
  return decoded;
}

}  // namespace ros2_messages_test
