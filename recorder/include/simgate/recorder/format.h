// simgate/recorder/format.h — what a simgate recording's MCAP file holds, for the recorder
// that writes it and the replay that reads it (docs/recording.md shows every message).
//
// Times: every message's log and publish time is the simulated time it is of, in nanoseconds
// (so Foxglove's timeline is the simulation's clock). Steps are the simulation's step count
// (Simulation::steps()) of the recorded run.
//
// Channels (message encoding "json" unless said):
//  /simgate/inputs         one message per input, in the order they took effect (the message's
//                          sequence: 1, 2, ...): {"seq", "step", "sim_time", "type", ...}
//                            type "request":   "transport", "client", "id", "component",
//                                              "service", "params" (the call's, as given)
//                            type "interrupt": "transport", "id", "reason" ("cancelled",
//                                              "timeout")
//                            type "command":   "component", "command", "refusal" ("" taken)
//                            type "tasks":     "count" (off-lock work taken in: a spawned
//                                              entity's model)
//  /simgate/outcomes       {"step", "sim_time", "transport", "id", "status", "failure",
//                           "message", "value" (when small)} per request ended
//  /simgate/state_hashes   {"first_step", "steps", "quantities": [names], "hashes": [one
//                           32-bit number per quantity per step, step by step]}: the state
//                           after each step (state_hash.h), in blocks
//  /simgate/initial_state  one message: {"step", "sim_time", "generation", "signature":
//                           "mjSTATE_INTEGRATION", "values": base64 of the mjtNum array}
//  /<component>            a stream's samples: its JSON, or Foxglove's schema where one fits
//                          (/<component>/calibration beside a camera's images)
// Metadata "simgate": simgate_version, mujoco_version, timestep, first_step, model_generation,
// hash_block. Attachments: "deployment.json" ({"document", "base_dir", "file"}), then the
// scene's MJCF under its file name.
#ifndef SIMGATE_RECORDER_FORMAT_H_
#define SIMGATE_RECORDER_FORMAT_H_

namespace simgate::recorder {

inline constexpr const char* k_inputs_topic = "/simgate/inputs";
inline constexpr const char* k_outcomes_topic = "/simgate/outcomes";
inline constexpr const char* k_hashes_topic = "/simgate/state_hashes";
inline constexpr const char* k_initial_state_topic = "/simgate/initial_state";
inline constexpr const char* k_metadata_name = "simgate";
inline constexpr const char* k_deployment_attachment = "deployment.json";

}  // namespace simgate::recorder

#endif  // SIMGATE_RECORDER_FORMAT_H_
