// simgate/core/service.h — a service: its descriptor, its typed invoker, and the async slot
// it shares with the other async services of its component.
//
// Terms:
//  - ServiceDescriptor: what every transport shows about a service (component, name,
//    parameters with JSON schemas and defaults, sync/async, local policy, doc).
//  - Service: a descriptor plus `invoke`, which converts bound JSON arguments to the C++
//    signature and calls the function.
//  - AsyncSlot: at most one async request runs per component; the slot remembers it and
//    how to interrupt() the component.
//  - concurrent service: an async service registered with .concurrent(). Each call runs
//    on its own, outside the component's slot: no preemption, no reject, any number at
//    once (every caller of `time sleep` gets its own sleep). Its function takes the
//    Completion first and finishes each call through it; a cancel ends that one call
//    PREEMPTED (Failure::cancelled) through the same completion, shutdown ends it FAILED
//    (Failure::shutdown), a deadline FAILED (Failure::timeout), and the component sees that
//    a call is over by its Completion::done() (then drops it), or is told at once by the
//    call's Completion::on_interrupt hook when it cannot wait for its next look.
//  - Completion: the handle an async request is finished with, exactly once, from any
//    thread (MORSE's result_setter / completed()).
//
// Services are built with make_service() (or Component::add_service /
// RequestManager::register_service, which call it): the parameter types come from the C++
// signature, the names and defaults from a Param list.
#ifndef SIMGATE_CORE_SERVICE_H_
#define SIMGATE_CORE_SERVICE_H_

#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "simgate/core/arguments.h"
#include "simgate/core/errors.h"
#include "simgate/core/status.h"

namespace simgate {

// Local interruption policy of an async service (MORSE @interruptible / @noninterruptible).
// unspecified: the receiving request manager's global policy decides.
enum class Policy : std::uint8_t { unspecified, interruptible, noninterruptible };

std::string_view to_string(Policy policy) noexcept;

// A parameter name with an optional default: {"x", "y", {"tolerance", 0.5}}.
struct Param {
  Param(const char* n) : name(n) {}
  Param(std::string n) : name(std::move(n)) {}
  template <class T>
  Param(std::string n, T default_value) : name(std::move(n)), default_value(json(default_value)) {}

  std::string name;                   // as used for named arguments
  std::optional<json> default_value;  // makes the parameter optional
};

struct ParamDescriptor {
  std::string name;                   // parameter name
  json schema;                        // JSON schema from the C++ type ({} = any)
  std::string type;                   // short type description ("number", "array of 3 numbers")
  std::optional<json> default_value;  // present for optional parameters
};

struct ServiceDescriptor {
  std::string component;                // "robot.waypoint", "simulation"
  std::string name;                     // "goto"
  std::vector<ParamDescriptor> params;  // in positional order
  bool is_async = false;                // completes later through a Completion
  bool concurrent = false;              // async only: each call runs on its own, outside the slot
  Policy policy = Policy::unspecified;  // async only (never for concurrent services)
  std::string doc;                      // one line
  json result_schema = json::object();  // JSON schema of the result ({} = unknown)
  // Acts on the whole process rather than the world (ends it, changes its log level):
  // served only through console transports (ServiceAccess::console, service_access.h).
  bool process_wide = false;
  // Whether a replay of a recording calls it again (the flight recorder, input_tap.h). False
  // for a service that acts on the loop or the process rather than the world (pause, play,
  // step, the lockstep, the time scale, recording itself, quit): a recording keeps the steps
  // and the inputs themselves, so its replay takes the steps without asking for them.
  bool replayed = true;

  std::string qualified_name() const { return component + "." + name; }
  std::size_t required_count() const;
  // "x, y, z, tolerance=0.5, speed=1.0"
  std::string signature() const;
  // {"component", "name", "async", "policy", "concurrent" (async only), "doc",
  //  "params": [{"name","schema","default"}], "process_wide": true (only when it is)}
  json to_json() const;
  // The JSON Schema of its arguments given by name: {"type": "object", "properties": each
  // parameter's schema (its default inside), "required": those without a default,
  // "description": the doc}. What Foxglove's service definitions and MCP's tools take.
  json params_schema() const;
};

namespace detail {

// The shared state of one running async request.
struct CallState;

// Where finished calls go: implemented by RequestManager (kept alive by shared_ptr so a
// component may complete a request after its manager is gone).
class CompletionSink {
 public:
  virtual ~CompletionSink() = default;
  virtual void finished(RequestId id, Outcome outcome) = 0;  // any thread
  // A progress report of a call whose client asked for them (Completion::progress).
  virtual void progressed(RequestId id, json value) = 0;  // any thread
};

struct CallState {
  RequestId id = 0;                    // the manager's request id
  std::string service;                 // "component.service", for messages
  std::weak_ptr<CompletionSink> sink;  // the manager that started it
  std::atomic<bool> finished{false};   // exactly-once guard
  bool concurrent = false;             // a call of a concurrent service (not in the slot)
  Failure interrupt_reason =
      Failure::preempted;         // set before interrupt(): preempted, cancelled or timeout
  std::string interrupt_message;  // who or what interrupted it
  // Its deadline passed (set under the simulation lock, after interrupt_message and
  // timeout_data, before interrupt()): whatever finishes it from then on, the outcome is
  // FAILED, Failure::timeout, interrupt_message (Completion::finish), so the client's one
  // reply is the timeout and the component's own completion afterwards is dropped.
  std::atomic<bool> timed_out{false};
  json timeout_data;  // the timeout outcome's data (null until then)
  // when it started, for the debug log line of its outcome; left at the epoch (and never
  // read) unless debug logging was on when it started
  std::chrono::steady_clock::time_point started{};
  // Progress reports (Completion::progress): the shortest time between two that reach the
  // client, or negative when its client asked for none (a report then costs one load).
  std::chrono::nanoseconds progress_interval{-1};
  // steady_clock time (ns since its epoch) of the last report passed on
  std::atomic<std::int64_t> last_progress_ns{std::numeric_limits<std::int64_t>::min()};
  // A concurrent call's Completion::on_interrupt hook (empty when none); set and run under
  // the simulation lock.
  std::function<void()> on_interrupt;
};

}  // namespace detail

// Finishes an async request. Copyable; every copy refers to the same request. Only the
// first call has an effect; later calls (and calls on an empty Completion) are ignored and
// return false. Thread-safe: may be called from any thread.
class Completion {
 public:
  Completion() = default;
  explicit Completion(std::shared_ptr<detail::CallState> state) : state_(std::move(state)) {}

  // MORSE's completed(status, result). A null result means "no result" (bare status line).
  bool operator()(Status status, json result = nullptr) const;
  // Finishes with a fully formed outcome (transport-facing; keeps Failure and message).
  bool finish(Outcome outcome) const;
  // Reports progress of the call (a JSON value: distance left, steps done...), any number
  // of times before it finishes. Passed on to the client only if it asked for progress
  // (Call::progress), at most once per its manager's progress interval (a report sooner
  // than that after the last one passed on is dropped), never after the call finished.
  // Returns true when it was passed on. Costs one load when nobody asked.
  bool progress(json value) const;
  // Whether a report now would be passed on (the client asked, the interval has passed, the
  // call runs): a component checks this before it builds a report, so that calls whose
  // clients did not ask cost nothing more.
  bool progress_due() const;

  bool done() const { return !state_ || state_->finished.load(); }
  // A call of a concurrent service: `hook` runs, under the simulation lock, right after the
  // core has ended the call from outside (its client cancelled it or left, its deadline
  // passed), for a component that must act at once rather than find the call done() at its
  // next look (a lockstep participant who leaves releases the others, even while the
  // simulation is paused and takes no step). Set it under the lock, when the call starts;
  // a later hook replaces it. Not run when the component finishes the call itself, nor at
  // shutdown.
  void on_interrupt(std::function<void()> hook) const;
  explicit operator bool() const { return state_ != nullptr; }
  const std::shared_ptr<detail::CallState>& state() const { return state_; }

 private:
  std::shared_ptr<detail::CallState> state_;  // null for an empty handle
};

// One component's async slot, shared by all its async services (and all the request
// managers that serve it). Touched only under the simulation lock.
struct AsyncSlot {
  std::string component;                        // owner's name
  std::shared_ptr<detail::CallState> running;   // the running request, if any (may be finished)
  Policy running_policy = Policy::unspecified;  // local policy of the running service
  Completion running_completion;                // handle to finish `running`
  // Ends the running request: Component::interrupt(), or finishing it PREEMPTED.
  std::function<void()> interrupt;
  // Calls of the component's concurrent services, outside the one-at-a-time rule: those
  // running, and some that finished since the last call started (pruned then). The
  // simulation ends those still running at shutdown.
  std::vector<std::shared_ptr<detail::CallState>> concurrent;

  bool busy() const { return running && !running->finished.load(); }
  // Completions of the concurrent calls still running.
  std::vector<Completion> running_concurrent() const;
};

class Service;

// Returned by registration calls to refine a service: .doc("..."), .interruptible().
class ServiceBuilder {
 public:
  explicit ServiceBuilder(Service& service) : service_(&service) {}
  ServiceBuilder& doc(std::string text);
  ServiceBuilder& interruptible();
  ServiceBuilder& noninterruptible();
  // Each call runs on its own (see `concurrent service` above). Async services whose
  // function takes a Completion first, with no interruption policy.
  ServiceBuilder& concurrent();
  ServiceBuilder& result_schema(json schema);
  // Acts on the whole process (ServiceDescriptor::process_wide): console transports only.
  ServiceBuilder& process_wide();
  // Not called again by a replay (ServiceDescriptor::replayed).
  ServiceBuilder& not_replayed();
  const ServiceDescriptor& descriptor() const;

 private:
  Service* service_;  // the service being configured (owned by its component or manager)
};

class Service {
 public:
  // Converts `args` (one pointer per parameter, defaults filled in) and calls the
  // function. For async services `completion` is the request's handle. Throws
  // WrongArguments for type mismatches and whatever the function throws.
  using Invoker = std::function<std::optional<json>(std::span<const json* const> args,
                                                    const Completion& completion)>;

  Service(ServiceDescriptor descriptor, Invoker invoker)
      : descriptor_(std::move(descriptor)), invoke_(std::move(invoker)) {}

  const ServiceDescriptor& descriptor() const { return descriptor_; }
  ServiceDescriptor& descriptor() { return descriptor_; }
  std::optional<json> invoke(std::span<const json* const> args, const Completion& c) const {
    return invoke_(args, c);
  }
  // The component's async slot (async services only).
  const std::shared_ptr<AsyncSlot>& slot() const { return slot_; }
  void set_slot(std::shared_ptr<AsyncSlot> slot) { slot_ = std::move(slot); }
  void set_invoker(Invoker invoker) { invoke_ = std::move(invoker); }
  // Whether the function takes the call's Completion as its first parameter.
  bool takes_completion() const { return takes_completion_; }
  void set_takes_completion(bool takes) { takes_completion_ = takes; }

 private:
  ServiceDescriptor descriptor_;     // what transports show
  Invoker invoke_;                   // typed call
  std::shared_ptr<AsyncSlot> slot_;  // shared with the component's other async services
  bool takes_completion_ = false;    // the function's first parameter is the Completion
};

// The arguments of one call: one pointer per parameter, into the request's params or to a
// default. Up to 8 parameters are held inline (no allocation per call).
class BoundArguments {
 public:
  explicit BoundArguments(std::size_t count) : count_(count) {
    if (count > inline_.size()) heap_.resize(count);
  }
  const json*& operator[](std::size_t i) { return data()[i]; }
  std::size_t size() const { return count_; }
  std::span<const json* const> span() const { return {data(), count_}; }

 private:
  const json** data() { return heap_.empty() ? inline_.data() : heap_.data(); }
  const json* const* data() const { return heap_.empty() ? inline_.data() : heap_.data(); }

  std::array<const json*, 8> inline_{};  // services with up to 8 parameters
  std::vector<const json*> heap_;        // the others
  std::size_t count_;                    // number of parameters
};

// Matches positional (array), named (object) or absent (null) parameters to the
// descriptor: one pointer per parameter, into `params` or to a default. Throws
// WrongArguments ("wrong # of parameters ...", or "parameters expected ...!" when none came,
// as MORSE words them; unknown names, non-list params).
BoundArguments bind_arguments(const ServiceDescriptor& service, const json& params);

// ---------------------------------------------------------------------------------------
// typed registration machinery

namespace detail {

template <class F>
struct fn_traits : fn_traits<decltype(&std::remove_cvref_t<F>::operator())> {};
template <class R, class... A>
struct fn_traits<R(A...)> {
  using result = R;
  using args = std::tuple<A...>;
};
template <class R, class... A>
struct fn_traits<R (*)(A...)> : fn_traits<R(A...)> {};
template <class R, class... A>
struct fn_traits<R (*)(A...) noexcept> : fn_traits<R(A...)> {};
template <class R, class... A>
struct fn_traits<R(A...) noexcept> : fn_traits<R(A...)> {};
template <class C, class R, class... A>
struct fn_traits<R (C::*)(A...)> : fn_traits<R(A...)> {
  using cls = C;
};
template <class C, class R, class... A>
struct fn_traits<R (C::*)(A...) const> : fn_traits<R(A...)> {
  using cls = C;
};
template <class C, class R, class... A>
struct fn_traits<R (C::*)(A...) noexcept> : fn_traits<R(A...)> {
  using cls = C;
};
template <class C, class R, class... A>
struct fn_traits<R (C::*)(A...) const noexcept> : fn_traits<R(A...)> {
  using cls = C;
};

// Binds a member function to an object, keeping its exact parameter list.
template <class C, class R, class... A>
auto bind_member(C* obj, R (C::*fn)(A...)) {
  return [obj, fn](A... a) -> R { return (obj->*fn)(std::forward<A>(a)...); };
}
template <class C, class R, class... A>
auto bind_member(C* obj, R (C::*fn)(A...) const) {
  return [obj, fn](A... a) -> R { return (obj->*fn)(std::forward<A>(a)...); };
}
template <class C, class R, class... A>
auto bind_member(C* obj, R (C::*fn)(A...) noexcept) {
  return [obj, fn](A... a) -> R { return (obj->*fn)(std::forward<A>(a)...); };
}
template <class C, class R, class... A>
auto bind_member(C* obj, R (C::*fn)(A...) const noexcept) {
  return [obj, fn](A... a) -> R { return (obj->*fn)(std::forward<A>(a)...); };
}

template <class Tuple>
struct first_is_completion : std::false_type {};
template <class First, class... Rest>
struct first_is_completion<std::tuple<First, Rest...>>
    : std::is_same<std::remove_cvref_t<First>, Completion> {};

template <class Tuple>
struct drop_first;
template <class First, class... Rest>
struct drop_first<std::tuple<First, Rest...>> {
  using type = std::tuple<Rest...>;
};
template <>
struct drop_first<std::tuple<>> {
  using type = std::tuple<>;
};

// Throws WrongArguments naming the parameter, the expected type and what was received.
[[noreturn]] void throw_type_mismatch(const ServiceDescriptor& d, std::size_t index,
                                      const TypeMismatch& mismatch);
// Throws std::logic_error: registration mistakes are programming errors.
[[noreturn]] void throw_registration_error(const std::string& what);

template <class T>
std::decay_t<T> convert_argument(const ServiceDescriptor& d, std::size_t index, const json& value) {
  try {
    return ArgTraits<std::decay_t<T>>::from_json(value);
  } catch (const TypeMismatch& m) {
    throw_type_mismatch(d, index, m);
  }
}

template <class R>
std::optional<json> result_to_json(R&& r) {
  json j;
  if constexpr (std::is_same_v<std::decay_t<R>, json> && !std::is_lvalue_reference_v<R>)
    j = std::move(r);  // a service's own JSON answer is taken, not copied node by node
  else
    j = ArgTraits<std::decay_t<R>>::to_json(r);
  if (j.is_null()) return std::nullopt;
  return j;
}

template <bool WithCompletion, class F, class... A, std::size_t... I>
std::optional<json> invoke_typed(F& fn, [[maybe_unused]] const ServiceDescriptor& d,
                                 [[maybe_unused]] std::span<const json* const> args,
                                 [[maybe_unused]] const Completion& completion,
                                 std::index_sequence<I...>) {
  // braced initialisation converts left to right: the first bad parameter is reported
  std::tuple<std::decay_t<A>...> values{convert_argument<A>(d, I, *args[I])...};
  auto call = [&]() -> decltype(auto) {
    if constexpr (WithCompletion)
      return fn(completion, std::forward<std::decay_t<A>>(std::get<I>(values))...);
    else
      return fn(std::forward<std::decay_t<A>>(std::get<I>(values))...);
  };
  using R = decltype(call());
  if constexpr (std::is_void_v<R>) {
    call();
    return std::nullopt;
  } else {
    return result_to_json(call());
  }
}

template <class F, class Tuple>
struct typed_invoker;
template <class F, class... A>
struct typed_invoker<F, std::tuple<A...>> {
  template <bool WithCompletion>
  static std::optional<json> run(F& fn, const ServiceDescriptor& d,
                                 std::span<const json* const> args, const Completion& completion) {
    return invoke_typed<WithCompletion, F, A...>(fn, d, args, completion,
                                                 std::index_sequence_for<A...>{});
  }
  static std::vector<ParamDescriptor> describe() {
    return {ParamDescriptor{"", ArgTraits<std::decay_t<A>>::schema(),
                            ArgTraits<std::decay_t<A>>::expected(), std::nullopt}...};
  }
  // a default must convert to its parameter's type: checked at registration
  static void check_defaults(const ServiceDescriptor& d) {
    std::size_t i = 0;
    (check_default<A>(d, i++), ...);
  }
  template <class T>
  static void check_default(const ServiceDescriptor& d, std::size_t i) {
    if (!d.params[i].default_value) return;
    try {
      (void)ArgTraits<std::decay_t<T>>::from_json(*d.params[i].default_value);
    } catch (const TypeMismatch& m) {
      throw_registration_error(d.qualified_name() + ": default of parameter '" + d.params[i].name +
                               "' is " + m.found + ", not " + m.expected);
    }
  }
};

// Fills descriptor params from the signature types and the Param list; validates.
void name_parameters(ServiceDescriptor& d, std::vector<ParamDescriptor> typed,
                     std::vector<Param> names);

}  // namespace detail

// Builds a service from any callable. Async callables may take a Completion first; those
// that don't must finish through their component's completed(). `params` names the
// parameters in order (defaults allowed); when empty they are named arg0, arg1...
template <class F>
std::shared_ptr<Service> make_service(std::string component, std::string name, F fn,
                                      std::vector<Param> params, bool is_async) {
  using Traits = detail::fn_traits<std::decay_t<F>>;
  using AllArgs = typename Traits::args;
  constexpr bool takes_completion = detail::first_is_completion<AllArgs>::value;
  using Args =
      std::conditional_t<takes_completion, typename detail::drop_first<AllArgs>::type, AllArgs>;
  using Invoker = detail::typed_invoker<std::decay_t<F>, Args>;

  ServiceDescriptor d;
  d.component = std::move(component);
  d.name = std::move(name);
  d.is_async = is_async;
  if (takes_completion && !is_async)
    detail::throw_registration_error(d.qualified_name() +
                                     ": only async services take a Completion parameter");
  detail::name_parameters(d, Invoker::describe(), std::move(params));
  Invoker::check_defaults(d);
  if constexpr (!std::is_void_v<typename Traits::result>)
    d.result_schema = ArgTraits<std::decay_t<typename Traits::result>>::schema();

  auto service = std::make_shared<Service>(std::move(d), nullptr);
  service->set_takes_completion(takes_completion);
  // the invoker reports errors with the final descriptor (docs and policy are set later)
  const Service* self = service.get();
  service->set_invoker(
      [fn = std::move(fn), self](std::span<const json* const> args,
                                 const Completion& c) mutable -> std::optional<json> {
        return Invoker::template run<takes_completion>(fn, self->descriptor(), args, c);
      });
  return service;
}

}  // namespace simgate

#endif  // SIMGATE_CORE_SERVICE_H_
