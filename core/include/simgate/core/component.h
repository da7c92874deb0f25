// simgate/core/component.h — a named object whose services transports expose.
//
// A Component (robot, actuator, sensor, or a pseudo-component such as `simulation`)
// registers its services in its constructor with add_service / add_async_service, then is
// handed to the request managers that serve it (RequestManager::register_component). All
// its methods run on the simulation thread: services, default_action(), interrupt().
//
// Async services (MORSE's @async_service): the start method returns quickly; the
// component finishes the request later with completed(status, result), typically from
// default_action(). At most one async request runs per component; a second one follows
// the running service's local policy (interruptible: the running one is interrupted and
// ends PREEMPTED; non-interruptible: the new one FAILS) or, without one, the receiving
// manager's global policy.
//
// Concurrent services (add_async_service(...).concurrent(), service.h) are the exception:
// each call takes its own Completion and runs beside the others and beside the slot's
// request. The component keeps the completions, finishes each one through it, and drops
// one when it is done() (cancelled by its client, or ended at shutdown).
//
// Data streams (MORSE's datastreams): a sensor declares an output stream (declare_output_stream:
// a function that reads one sample, its get_local_data), an actuator an input stream
// (declare_input_stream: a function that applies one command, MORSE's local_data a client
// writes). The configuration says which transports carry a component's stream and how often
// (its `frequency`); StreamHub (streams.h) runs them. One stream per component, as in MORSE.
// A component whose samples are ready only later (a camera's images, rendered on another
// thread) declares a pushed stream instead (declare_pushed_stream): it asks whether anyone
// wants samples (stream_wanted) and pushes each one when it has it (push_sample). A component
// that tells of things as they happen (the simulation's events: a divergence, a pause)
// declares an event stream (declare_event_stream): a pushed stream with no rate.
#ifndef SIMGATE_CORE_COMPONENT_H_
#define SIMGATE_CORE_COMPONENT_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "simgate/core/service.h"

namespace simgate {

class StreamOutlet;    // streams.h
struct StreamPayload;  // streams.h

// Which way a stream's data flows: out of the simulation (a sensor's samples) or in (an
// actuator's commands). MORSE's words on the wire: "OUT", "IN".
enum class StreamDirection : std::uint8_t { out, in };
const char* to_string(StreamDirection direction);

// A component's stream, as it declares it.
struct StreamDeclaration {
  StreamDirection direction = StreamDirection::out;
  // What the data is: "pose", "odometry", "imu", "joint_state", "laser_scan", "velocity"...
  // A transport with typed messages (DDS) picks its type by it; any other is carried as JSON.
  std::string kind;
  // out: reads one sample (the component's get_local_data), under the simulation lock.
  std::function<json()> produce;
  // in: applies one command (a JSON object, MORSE's local_data), under the simulation lock;
  // throws ServiceError to refuse it (the message says what was wrong).
  std::function<void(const json&)> apply;
  // in: the keys a command takes, for introspection and docs ({"v", "w"}).
  // out, with produce_record: the names of the record's numbers, in its order.
  std::vector<std::string> fields;
  // out, for a sample that is a flat object of numbers (a pose, an odometry): writes the
  // numbers `fields` names into its argument (as many), without building JSON. A transport
  // with typed messages reads them as they are (StreamSample::number); the JSON object is
  // made from them only when a transport needs it. Empty for any other sample; produce()
  // is then the record as JSON.
  std::function<void(std::span<double>)> produce_record;
  // out, pushed (declare_pushed_stream): the component's link to the hub that runs the
  // stream; produce is empty (the hub never asks, the component pushes). Null otherwise.
  std::shared_ptr<StreamOutlet> outlet;
  // out, pushed: the samples per simulated second the component pushes while the stream is
  // wanted (listed as the stream's frequency); 0 for an event stream (declare_event_stream:
  // samples come as things happen, listed with frequency 0).
  double pushed_frequency = 0;
};

// The most numbers a record sample has.
inline constexpr std::size_t k_max_record_fields = 16;
// A record as the JSON object a client sees: {fields[i]: values[i]}.
json record_json(const std::vector<std::string>& fields, std::span<const double> values);

class Component {
 public:
  explicit Component(std::string name);
  virtual ~Component() = default;
  Component(const Component&) = delete;
  Component& operator=(const Component&) = delete;

  // Full name, e.g. "robot.waypoint" or "simulation".
  const std::string& name() const { return name_; }

  // Called once per simulation step, after requests are processed and before physics.
  virtual void default_action() {}

  // Ends the running async request. Override to really stop what it does (halt the robot)
  // and call Component::interrupt() last; the default completes it PREEMPTED. If an
  // override forgets, the request manager ends the request PREEMPTED anyway.
  virtual void interrupt();

  // Finishes the running async request (MORSE's completed). Ignored, with a warning,
  // when none is running.
  void completed(Status status, json result = nullptr);
  // Reports progress of the running async request (Completion::progress: reaches its client
  // only if it asked, rate-limited). False, and nothing sent, when none is running.
  bool progress(json value);
  // Whether a report of the running request now would reach its client
  // (Completion::progress_due): check it before building one.
  bool progress_due() const;

  // True while an async request of this component is running.
  bool has_running_request() const { return slot_->busy(); }
  // "component.service" of the running request, or "".
  std::string running_service() const;

  // Every service registered by the component, in registration order.
  const std::vector<std::shared_ptr<Service>>& services() const { return services_; }
  // The slot shared by this component's async services.
  const std::shared_ptr<AsyncSlot>& async_slot() const { return slot_; }
  // Its stream, or null when it declared none.
  const StreamDeclaration* stream() const { return stream_ ? &*stream_ : nullptr; }
  // Whether the pushed stream has subscribers now (an atomic read, cheap enough for every
  // step): make samples only while it does. False without a pushed stream.
  bool stream_wanted() const;

 protected:
  // add_service("set_speed", &MotionVW::set_speed, {"v", "w"}).doc("...");
  // fn: a member function of the derived class, or any callable.
  template <class F>
  ServiceBuilder add_service(std::string name, F fn, std::vector<Param> params = {}) {
    return add(std::move(name), std::move(fn), std::move(params), false);
  }
  // add_async_service("goto", &Waypoint::go_to, {"x", "y", "z", {"tolerance", 0.5}})
  //     .interruptible();
  template <class F>
  ServiceBuilder add_async_service(std::string name, F fn, std::vector<Param> params = {}) {
    return add(std::move(name), std::move(fn), std::move(params), true);
  }
  // A sensor's stream: `produce` reads one sample (usually get_local_data).
  //   declare_output_stream("pose", [this] { return get_local_data(); });
  void declare_output_stream(std::string kind, std::function<json()> produce);
  // A sensor whose sample is a flat object of numbers: `fields` names them (at most
  // k_max_record_fields), `produce` writes them in that order. Cheaper to stream than JSON.
  //   declare_output_stream("pose", {"x", "y", "z"}, [this](std::span<double> v) { ... });
  void declare_output_stream(std::string kind, std::vector<std::string> fields,
                             std::function<void(std::span<double>)> produce);
  // A stream whose samples the component pushes when they are ready (push_sample), rather
  // than the hub reading one when it is due: for samples made off the simulation thread
  // (a camera's images). `frequency`: how many per simulated second it pushes while
  // stream_wanted() (> 0; the component keeps that rate itself).
  //   declare_pushed_stream("image", frequency_);
  void declare_pushed_stream(std::string kind, double frequency);
  // A pushed stream with no rate: a sample is pushed (push_sample) each time something
  // happens that subscribers are to be told of, at most a few per step. Listed with
  // frequency 0; the configuration's frequency does not apply to it.
  //   declare_event_stream("events");
  void declare_event_stream(std::string kind);
  // Pushes one sample of the pushed stream, of the simulated time `time`: JSON, or a binary
  // payload (bytes JSON transports see through its to_json, streams.h). Under the
  // simulation lock (a service, default_action()); fanned out to the subscribers as a
  // produced sample is. False when nobody took it (no subscriber, no hub, no pushed stream).
  bool push_sample(double time, json data);
  bool push_sample(double time, std::shared_ptr<const StreamPayload> payload);
  // A pushed stream's sample that was due and will never come (a camera's image skipped
  // because its render thread is behind): counted in the stream's statistics, as `skipped`
  // and among its `dropped`. Under the simulation lock; ignored without a pushed stream.
  void note_skipped_sample();
  // An actuator's stream: `apply` takes one command object with the keys `fields`.
  //   declare_input_stream("velocity", {"v", "w"}, [this](const json& c) { ... });
  void declare_input_stream(std::string kind, std::vector<std::string> fields,
                            std::function<void(const json&)> apply);

 private:
  template <class F>
  ServiceBuilder add(std::string name, F fn, std::vector<Param> params, bool is_async) {
    std::shared_ptr<Service> service;
    if constexpr (std::is_member_function_pointer_v<F>) {
      using C = typename detail::fn_traits<F>::cls;
      service = make_service(name_, std::move(name), detail::bind_member(static_cast<C*>(this), fn),
                             std::move(params), is_async);
    } else {
      service = make_service(name_, std::move(name), std::move(fn), std::move(params), is_async);
    }
    return adopt(std::move(service));
  }
  ServiceBuilder adopt(std::shared_ptr<Service> service);

  std::string name_;                                // full component name
  std::shared_ptr<AsyncSlot> slot_;                 // the one running async request
  std::vector<std::shared_ptr<Service>> services_;  // registration order
  std::optional<StreamDeclaration> stream_;         // its stream, if it has one
};

}  // namespace simgate

#endif  // SIMGATE_CORE_COMPONENT_H_
