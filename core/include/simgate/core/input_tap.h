// simgate/core/input_tap.h — every input that reaches the simulation, as it reaches it: what a
// flight recorder (issue #39) writes down so that a replay can apply the same inputs at the
// same steps.
//
// An input is anything from outside that can change the world: a request that a service ran
// (from any transport), a cancel or a deadline that interrupted a running one, a command
// applied to an input stream. The simulation's own work (its steps, its components' default
// actions, what an async request does step by step) is not an input: given the same inputs
// at the same steps it is the same.
//
// One tap at most is set on a simulation's gate (SimulationGate::set_input_tap); the request
// managers and the stream hub of that gate call it. Every call is made on the thread that
// holds the simulation lock, at the moment the input takes effect, in the order they take
// effect; a tap must not block, and must not call back into the manager or the hub (copy
// what it needs and leave). Setting or clearing the tap is done under the simulation lock.
#ifndef SIMGATE_CORE_INPUT_TAP_H_
#define SIMGATE_CORE_INPUT_TAP_H_

#include <string>
#include <string_view>

#include "simgate/core/status.h"

namespace simgate {

class RequestManager;
struct Call;

class InputTap {
 public:
  virtual ~InputTap() = default;

  // `call`, request `id` of `manager`'s transport, is about to run (its service, or the
  // refusal of an unknown service or bad arguments). Not called for a request answered
  // without running (past its deadline while it waited for the lock).
  virtual void request_started(const RequestManager& manager, RequestId id, const Call& call) = 0;
  // The final outcome of a request request_started() announced: at once for a sync one,
  // when it ends for an async one.
  virtual void request_ended(const RequestManager& manager, RequestId id,
                             const Outcome& outcome) = 0;
  // A running async request is being interrupted from outside its service: its client
  // cancelled it (Failure::cancelled) or its deadline passed (Failure::timeout). Called before
  // the component is told.
  virtual void request_interrupted(const RequestManager& manager, RequestId id, Failure reason) = 0;
  // A command was applied to the input stream of `component`: `refusal` is empty when the
  // component took it, else why it did not.
  virtual void command_applied(std::string_view component, const json& command,
                               const std::string& refusal) = 0;
};

}  // namespace simgate

#endif  // SIMGATE_CORE_INPUT_TAP_H_
