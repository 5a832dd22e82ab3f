#pragma once
/// @file
/// Cyclone DDS's own serializer and deserializer for the generated types, reached the way a
/// writer and a reader reach them: through the sertype of a topic (ddsi_serdata_from_sample,
/// ddsi_serdata_to_ser, ddsi_serdata_from_ser_iov, ddsi_serdata_to_sample).

#include <cstdint>
#include <vector>

#include <dds/dds.h>

struct ddsi_sertype;

namespace ros2_messages_test {

/// The sertype Cyclone built for a topic of this descriptor, in a private domain that lives until
/// the process ends. Fails the calling test (and returns null) if Cyclone refuses.
const ddsi_sertype* sertype_of(const dds_topic_descriptor_t* descriptor);

/// The serialized form Cyclone's writer would put on the wire: encapsulation header and payload.
std::vector<uint8_t> cyclone_serialize(const ddsi_sertype* type, const void* sample);

/// What Cyclone's reader does with received bytes: validate (dds_stream_normalize) and decode
/// into `sample`, which must be zero-initialized. False if either step rejects the bytes.
bool cyclone_deserialize(const ddsi_sertype* type, const std::vector<uint8_t>& bytes, void* sample);

}  // namespace ros2_messages_test
