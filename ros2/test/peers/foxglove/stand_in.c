/* A stand-in for cartesian_impedance_ros2, so that the @foxglove/ros2 peer is tested even where the
 * node is not built: plain Cyclone DDS with the generated C types and the node's wire rules (topic
 * "rt" + fully-qualified name, reliable, volatile, keep-last 10, XCDR1 only). Its arm is ideal:
 * <fq>/controller_state reports current_pose = the last <fq>/reference_pose received, at 100 Hz,
 * and <fq>/full_state the stiffness given on the command line, with status "ok", a cycle count and
 * the safety layer of an arm at rest.
 *   stand_in DOMAIN FQ_NAME STIFFNESS_TRANSLATION STIFFNESS_ROTATION   (runs until SIGINT/SIGTERM)
 */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dds/dds.h"
#include "ros2_messages.h"

static volatile sig_atomic_t stop = 0;

static void on_signal(int signal_number) {
  (void)signal_number;
  stop = 1;
}

static dds_entity_t topic(dds_entity_t participant, const dds_topic_descriptor_t* descriptor,
                          const char* fq, const char* name) {
  char dds_name[256];
  snprintf(dds_name, sizeof dds_name, "rt%s/%s", fq, name);
  return dds_create_topic(participant, descriptor, dds_name, NULL, NULL);
}

static void wrench(struct geometry_msgs_msg_dds__Wrench_* w, double force, double torque) {
  w->force.x = w->force.y = w->force.z = force;
  w->torque.x = w->torque.y = w->torque.z = torque;
}

int main(int argc, char** argv) {
  if (argc != 5) {
    fprintf(stderr, "usage: %s DOMAIN FQ_NAME STIFFNESS_TRANSLATION STIFFNESS_ROTATION\n", argv[0]);
    return 2;
  }
  const dds_domainid_t domain = (dds_domainid_t)atoi(argv[1]);
  const char* fq = argv[2];
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);

  dds_qos_t* qos = dds_create_qos();
  dds_qset_userdata(qos, "enclave=/;", 10);
  const dds_entity_t participant = dds_create_participant(domain, qos, NULL);
  if (participant < 0) {
    fprintf(stderr, "stand_in: dds_create_participant: %s\n", dds_strretcode(-participant));
    return 1;
  }
  dds_reset_qos(qos);
  /* 100 ms is the writer default, which Cyclone then leaves out of its announcements: the peer
   * must cope with that (see acceptDefaultReliability in peer.js). */
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  const dds_entity_t reader = dds_create_reader(
      participant,
      topic(participant, &geometry_msgs_msg_dds__PoseStamped__desc, fq, "reference_pose"), qos,
      NULL);
  const dds_entity_t state_writer = dds_create_writer(
      participant,
      topic(participant, &cartesian_impedance_controller_msg_dds__ControllerState__desc, fq,
            "controller_state"),
      qos, NULL);
  const dds_entity_t full_writer =
      dds_create_writer(participant,
                        topic(participant, &cartesian_impedance_msgs_msg_dds__ControllerState__desc,
                              fq, "full_state"),
                        qos, NULL);
  dds_delete_qos(qos);
  if (reader < 0 || state_writer < 0 || full_writer < 0) {
    fprintf(stderr, "stand_in: could not create the endpoints\n");
    return 1;
  }

  /* The node's start: the Panda's ready pose, flange pointing down. */
  struct geometry_msgs_msg_dds__Pose_ pose = {{0.307, 0.0, 0.590}, {1.0, 0.0, 0.0, 0.0}};
  cartesian_impedance_controller_msg_dds__ControllerState_ state;
  cartesian_impedance_msgs_msg_dds__ControllerState_ full;
  memset(&state, 0, sizeof state);
  memset(&full, 0, sizeof full);
  char empty[] = "", ok[] = "ok", base[] = "base", idle[] = "idle", none[] = "none";
  state.header.frame_id = full.header.frame_id = empty;
  full.status = ok;
  full.stiffness_frame = full.wrench_frame = base;
  full.trajectory_state = idle;
  /* The limits and the safety layer of an arm at rest: nothing shaped or capped, the energy tank
   * full (config/panda.yaml: 5 mJ), no payload declared and none estimated. */
  full.torque_shaping = none;
  full.torque_shaping_scale = 1.0;
  full.translation_drive_scale = full.rotation_drive_scale = 1.0;
  full.force_scale = full.torque_scale = 1.0;
  full.tank_level = 0.005;
  full.stiffness_change_scale = 1.0;
  full.payload_estimate_valid = true;
  wrench(&state.cartesian_stiffness, atof(argv[3]), atof(argv[4]));
  full.cartesian_stiffness = full.commanded_cartesian_stiffness = state.cartesian_stiffness;
  /* Seven joints' worth of names and arrays: full_state about as large as the node's (1.5 kB). */
  char* names[7] = {"panda_joint1", "panda_joint2", "panda_joint3", "panda_joint4",
                    "panda_joint5", "panda_joint6", "panda_joint7"};
  double joints[7] = {0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785};
  dds_sequence_double seven = {7, 7, joints, false};
  full.joint_state.name._length = full.joint_state.name._maximum = 7;
  full.joint_state.name._buffer = names;
  full.joint_state.position = full.joint_state.velocity = seven;
  full.nullspace_config = full.nullspace_stiffness = full.commanded_torques = seven;
  full.cartesian_torques = full.nullspace_torques = full.wrench_torques = seven;
  full.gravity_torques = seven;

  void* samples[1] = {NULL};
  dds_sample_info_t info;
  while (!stop) {
    while (dds_take(reader, samples, &info, 1, 1) > 0) {
      if (info.valid_data) {
        pose = ((geometry_msgs_msg_dds__PoseStamped_*)samples[0])->pose;
      }
      dds_return_loan(reader, samples, 1);
    }
    const dds_time_t now = dds_time();
    state.header.stamp.sec = full.header.stamp.sec = (int32_t)(now / DDS_NSECS_IN_SEC);
    state.header.stamp.nanosec = full.header.stamp.nanosec = (uint32_t)(now % DDS_NSECS_IN_SEC);
    state.current_pose = full.current_pose = pose;
    full.cycle += 10;
    full.time = (double)full.cycle * 1e-3;
    dds_write(state_writer, &state);
    dds_write(full_writer, &full);
    dds_sleepfor(DDS_MSECS(10));
  }
  dds_delete(participant);
  return 0;
}
