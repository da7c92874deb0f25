// simgate/core/request_manager.h — the base of every transport (MORSE's RequestManager).
//
// A request manager owns a table of services (registered by hand, or a component's), a
// queue of requests handed over by its transport, and the life cycle of each request:
//
//   I/O thread:  id = new_request_id() (or kit::RequestSlots::insert(client)); remember
//                (client, id); run_or_submit(id, call)
//   either:      the simulation lock is free (the loop waits for its next step): the I/O
//                thread takes it and runs process() itself, at once
//   or:          the lock is held (the loop is stepping): the request is queued and the
//                simulation thread's next process() runs it
//   process():   on_incoming_request() -> sync: runs, on_service_completion()
//                                      -> async: started; later the component calls
//                                         completed() -> next process()
//                                         -> on_service_completion()
//   transport:   on_service_completion() sends the reply. A transport with its own I/O
//                thread names it (deliver_on_this_thread): outcomes produced on other
//                threads are then handed over by the core, which wakes that thread, so
//                on_service_completion runs on the transport's thread only.
//
// Every submitted request gets exactly one on_service_completion() (even unknown services,
// bad arguments, requests still running at stop() and requests past their deadline).
//
// Deadlines: a call may carry a timeout (Call::timeout), and a manager a maximum wait
// (set_max_wait); the shorter one, counted from submission, bounds the wait for the reply.
// When it passes, the request ends FAILED with Failure::timeout: an async request is
// interrupted as a cancel interrupts it (the component's interrupt(), on the thread that
// holds the simulation lock), and whatever the component completes afterwards is dropped; a
// request still queued when it passes (it waited for the lock) is answered without running.
// A sync service that has started runs to completion (nothing interrupts it under the lock)
// and its outcome is the reply. The deadlines are kept in a heap checked by process(),
// which the gate wakes when the earliest is due (SimulationGate::wake_at): no thread or
// timer per request, and a call without a deadline reads no clock. Services run only under the
// simulation lock (SimulationGate), on whichever thread runs process(); while one runs,
// CallContext::current() names the manager and the request (call_context.h), so a service
// keeps to the components its caller's transport serves. A manager's ServiceAccess (its
// transport's allow and deny lists, service_access.h) narrows what its clients may call:
// a denied service is answered as an unknown one before anything runs, and descriptors()
// leave it out. submit() and
// cancel() are thread-safe and never block for long; a queued request wakes process() at
// once.
//
// A component can come and leave while the manager runs (register_component: a robot
// spawned at run time; unregister_component: one deleted): a leaving one's running requests
// end FAILED with the reason, its services leave the table; either way
// on_services_changed() tells the transport.
//
// A transport plugin subclasses RequestManager, does its I/O on its own threads between
// start() and stop(), and overrides on_service_completion(). See
// docs/writing-a-transport.md.
#ifndef SIMGATE_CORE_REQUEST_MANAGER_H_
#define SIMGATE_CORE_REQUEST_MANAGER_H_

#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "simgate/core/component.h"
#include "simgate/core/service.h"
#include "simgate/core/service_access.h"
#include "simgate/core/status.h"
#include "simgate/core/streams.h"
#include "simgate/core/simulation_gate.h"

namespace simgate {

// What to do with a new async request when the running one has no local policy.
enum class GlobalPolicy : std::uint8_t {
  reject,   // the new request FAILS (MORSE's behaviour, the default)
  preempt,  // the running request is interrupted (PREEMPTED), the new one starts
};

// One request as a transport hands it over.
struct Call {
  std::string component;  // "robot.waypoint"
  std::string service;    // "goto"
  json params;            // array (positional), object (named) or null (no arguments)
  bool progress = false;  // the client asked for progress reports (on_service_progress)
  // The longest the client waits for the reply, counted from when the core receives the
  // call (submit, run_or_submit); zero (or negative) = no limit of its own, the manager's
  // max wait may still apply. A duration rather than a time point: it is what clients send
  // (JSON-RPC's _meta.timeout_ms, DDS's timeout_ms), transports need no clock, and a call
  // without one costs no clock read anywhere; the core stamps the deadline once, at
  // submission, so that time spent queued for the lock counts.
  std::chrono::milliseconds timeout{0};
  // The transport sends this caller the result's attachments (Outcome::attachments) raw
  // instead of what the records encode (DDS, to a client that reads its replies' images
  // raw): a service may then leave the encoded copy out of its records (a camera: no PNG),
  // and must still attach the raw bytes. CallContext::takes_raw_attachments() while it runs.
  bool raw_attachments = false;
  // The client the call came from: a number the transport gives each connection (or DDS
  // client), unique within the transport for the process's life; 0: not said. What a
  // service keeps for its caller (a saved state) is keyed by it (CallContext::client()), and
  // RequestManager::client_connected() says whether that client is still there.
  std::uint64_t client = 0;
};

namespace detail {
class Inbox;
class Handoff;
}  // namespace detail

class RequestManager {
 public:
  // `name` appears in error messages: "Socket service manager".
  explicit RequestManager(std::string name);
  virtual ~RequestManager();
  RequestManager(const RequestManager&) = delete;
  RequestManager& operator=(const RequestManager&) = delete;

  const std::string& name() const { return name_; }

  // ---- registration (before start(), or on the process() thread) ----

  // A free function as a service of a (pseudo-)component (MORSE's register_service):
  //   rm.register_service("test_component", add, "add", {"a", "b"});
  template <class F>
  ServiceBuilder register_service(const std::string& component, F fn, std::string service_name,
                                  std::vector<Param> params = {}) {
    return add_service(
        make_service(component, std::move(service_name), std::move(fn), std::move(params), false));
  }
  // An async free function; it may take a Completion first (MORSE's result_setter):
  //   rm.register_async_service("test_component", start_computation, "compute", {"start"});
  template <class F>
  ServiceBuilder register_async_service(const std::string& component, F fn,
                                        std::string service_name, std::vector<Param> params = {}) {
    return add_service(
        make_service(component, std::move(service_name), std::move(fn), std::move(params), true));
  }
  // Serves every service of `component` (shared, not copied: the component must outlive
  // this manager's use of it); then on_services_changed(). Before start(), or under the
  // simulation lock (a robot spawned at run time).
  void register_component(Component& component);
  // Stops serving `component` (a robot deleted at run time): its async requests running
  // here end FAILED (Failure::service_error) with `reason`, each delivered as any outcome
  // (on the next process()); its services leave the table, so later calls of them are
  // refused as unknown ones, and descriptors() leaves them out; then
  // on_services_changed(). Under the simulation lock (or before start()); the component
  // may be destroyed once every manager serving it has been told. Returns whether it was
  // served here.
  bool unregister_component(const std::string& component, const std::string& reason);
  // Low level: adds one service (replacing one with the same component and name).
  // Async services without a slot get this manager's slot for their component.
  ServiceBuilder add_service(std::shared_ptr<Service> service);

  // Which registered services clients may call through this manager (its transport's allow
  // and deny lists; by default everything). A denied service is refused as an unknown one
  // (Failure::unknown_service, the same message a missing service gets, so the lists do not
  // show through) before its arguments are even read, and is left out of descriptors(),
  // services() and unknown-service messages. Services registered before or after alike.
  // Before start() (the gateway sets it before registering the components).
  void set_access(ServiceAccess access);
  ServiceAccess access() const;

  // Descriptors of every service a client may call through this manager: registered and
  // allowed by access() (thread-safe snapshot). What every transport's introspection shows.
  std::vector<ServiceDescriptor> descriptors() const;
  // MORSE's services(): component -> service names (the callable ones, as descriptors()).
  std::map<std::string, std::vector<std::string>> services() const;
  // Whether `component` is registered here (the mapping: the components this transport
  // serves, whether or not access() lets any of their services through).
  bool serves_component(const std::string& component) const;
  // Whether a client may call `component`.`service` through this manager: registered here
  // and allowed by access(). Any thread.
  bool may_call(const std::string& component, const std::string& service) const;
  // Every component this manager serves, with or without services, sorted (what
  // "component" counts in logs and banners).
  std::vector<std::string> components() const;

  // The shortest time between two progress reports of one call that reach its client
  // (Completion::progress); sooner ones are dropped. Before start().
  void set_progress_interval(std::chrono::nanoseconds interval) { progress_interval_ = interval; }
  std::chrono::nanoseconds progress_interval() const { return progress_interval_; }
  static constexpr std::chrono::milliseconds k_default_progress_interval{50};

  // The longest any request of this manager waits for its reply (the server-wide
  // requests.max_wait_ms of the config); zero = no limit. A call's own shorter timeout
  // wins. Before start().
  void set_max_wait(std::chrono::milliseconds max_wait) { max_wait_ = max_wait; }
  std::chrono::milliseconds max_wait() const { return max_wait_; }

  void set_global_policy(GlobalPolicy policy) { global_policy_ = policy; }
  GlobalPolicy global_policy() const { return global_policy_; }

  // The gate shared with the simulation loop and the other managers (default: one of its
  // own). Before start().
  void set_gate(std::shared_ptr<SimulationGate> gate);
  const std::shared_ptr<SimulationGate>& gate() const { return gate_; }

  // The simulation's data streams and the name this manager's transport has in the
  // configuration (what StreamHub::streams(transport) and subscribe() take). Before start();
  // without it the transport carries no stream.
  void set_streams(std::shared_ptr<StreamHub> hub, std::string transport);
  // What the transport reaches streams through (null: none): its simulation's, and those of
  // the worlds it serves as "w<k>/<component>" (attach_world; docs/worlds.md).
  const std::shared_ptr<StreamDirectory>& streams() const { return streams_; }
  const std::string& transport_name() const { return transport_name_; }
  // What `simulation details` names this transport's datastreams by (MORSE's
  // stream_interfaces: the datastream class). Default: "simgate.<transport>.publisher" for
  // output streams, ".reader" for input ones; the socket transport answers MORSE's classes.
  virtual std::string datastream_class(StreamDirection direction) const;

  // ---- life cycle (host thread) ----

  // Starts the transport's I/O. Called once, after registration. Must not throw.
  virtual void start() {}
  // Stops the I/O; idempotent; after it returns the transport calls nothing on the core.
  // Requests still pending are finished with Failure::shutdown by the destructor.
  virtual void stop() {}
  // Human-readable endpoints ("tcp://127.0.0.1:4000") once started or bound.
  virtual std::vector<std::string> endpoints() const { return {}; }

  // ---- the simulation thread ----

  // Executes queued requests and cancels, then delivers finished async requests, and ends
  // those past their deadline. Waits up to `wait` for work when there is none (without the
  // simulation lock; the earliest deadline of any manager of the gate shortens it), then
  // takes the lock for the work. Returns the number of events handled. Calls start() first
  // if nobody has. Must not be called with the simulation lock held.
  std::size_t process(std::chrono::nanoseconds wait = std::chrono::nanoseconds::zero());

  // Executes one request now (MORSE's on_incoming_request). Sync: returns the outcome.
  // Async: starts it and returns nullopt (the outcome arrives through
  // on_service_completion). Errors return a FAILED outcome. Under the simulation lock.
  std::optional<Outcome> on_incoming_request(RequestId id, const Call& call);

  // ---- the transport side (any thread) ----

  RequestId new_request_id();
  // Queues a request for the next process().
  void submit(RequestId id, Call call);
  // Queues several requests so that they all run in the same process() (JSON-RPC batches).
  void submit_batch(std::vector<std::pair<RequestId, Call>> calls);
  // Queues the requests (in one batch), then, if the simulation lock is free, takes it and
  // runs process() on this thread: the outcomes of sync requests (and of anything else
  // this manager had queued) reach on_service_completion before this returns, on this
  // thread. If the lock is held, the requests wait for the holder's next process(), as
  // with submit_batch(). Returns true if they ran here. The caller must not hold anything
  // its own on_service_completion() needs.
  bool run_or_submit(std::vector<std::pair<RequestId, Call>> calls);
  bool run_or_submit(RequestId id, Call call);
  // The same without moving the calls: those that are queued are moved from; those that
  // run here are left in place. `refilled`: the caller refills these objects for its next
  // requests (their strings and arrays keep their capacity; params of numbers, booleans
  // and nulls are left for the next parse to overwrite, anything else is released).
  // Otherwise (false) it drops them: their params are emptied, so that destroying them
  // costs no allocation.
  bool run_or_submit(std::span<std::pair<RequestId, Call>> calls, bool refilled = true);
  // Cancels a running async request of this manager: it ends PREEMPTED with
  // Failure::cancelled (the component's interrupt() ends it; a call of a concurrent
  // service is ended through its completion). `done(found)` runs on the simulation thread
  // afterwards.
  void cancel(RequestId id, std::function<void(bool found)> done = {});
  // Runs `task` on the simulation thread, in order with requests (e.g. introspection that
  // must see a consistent state).
  void post(std::function<void()> task);

  // Delivers `outcome` to request `id` (an id the transport allocated for an answer of its
  // own: an error, a cancel's answer) after everything submitted, cancelled or posted before
  // this call has been handled, through the same path as the core's outcomes. Any thread.
  void answer_in_order(RequestId id, Outcome outcome);

  // Number of async requests started and not yet finished (under the simulation lock).
  std::size_t pending_count() const { return running_.size(); }
  // Requests executed so far, whatever their outcome (unknown services and bad arguments
  // included). Any thread.
  std::uint64_t requests_handled() const {
    return requests_handled_.load(std::memory_order_relaxed);
  }
  // Clients connected now (TCP connections, DDS writers), for status lines. Transports
  // override it; the default knows of none. Any thread; must not block.
  virtual std::size_t client_count() const { return 0; }
  // Whether client `client` (a Call::client of this transport) is connected now: between
  // the transport's client_arrived() and client_left() for it. False for 0. Any thread.
  bool client_connected(std::uint64_t client) const;

  // Finishes every request not yet answered (queued or running async) FAILED with
  // Failure::shutdown, delivering each through on_service_completion, and refuses later
  // submissions the same way. Simulation thread (or the host once the loop has ended),
  // before stop(): this is how clients get a reply at shutdown. Takes the simulation lock.
  void abandon_pending(const std::string& reason = "the simulation is shutting down");

  // ---- worlds (issue #43, docs/worlds.md; request_manager_worlds.cc)
  // A world is another simulation of the process, under a lock of its own; its components
  // are served by a manager of their own, which this one (the transport's) routes to: a
  // call of component "w<k>/<name>" runs as <name> in world k, on world k's lock, and its
  // outcome (progress too) comes back here, to on_service_completion, like any other.
  // "w0/<name>" is <name>: this manager's own, world 0. descriptors(), services(),
  // components(), serves_component() and may_call() include the worlds' services under
  // their prefix; a call to a world there is not is answered FAILED naming those there are.
  // The manager world `world` (1, 2, ...) serves through this transport, made at the first
  // call and given to `prepare` before any call can reach it: there its simulation adds it
  // (Simulation::add_request_manager: its gate) and registers its components on it. Any
  // thread.
  std::shared_ptr<RequestManager> attach_world(
      unsigned world,
      const std::function<void(const std::shared_ptr<RequestManager>&)>& prepare = {});
  // Stops routing to `world`: once its simulation has shut its manager down (calls still
  // sent to it are answered by it, FAILED). Any thread.
  void detach_world(unsigned world);
  // The worlds attached, in order.
  std::vector<unsigned> worlds() const;
  // "no world 'w7' (the worlds here: w0, w1, w2)": what a call or a stream of world `world`,
  // which is not attached, is told. With the names (world_names()).
  std::string no_world(unsigned world) const;
  // "w0" and the attached worlds' names, in order.
  std::vector<std::string> world_names() const;
  // "w<k>/<name>": k and where <name> starts, or nullopt (not a world's address).
  static std::optional<std::pair<unsigned, std::size_t>> world_address(std::string_view component);
  // World k's name, "w<k>" (its components' prefix is that and "/").
  static std::string world_name(unsigned world) { return "w" + std::to_string(world); }

 protected:
  // Delivers the final outcome of request `id`, exactly once per submitted request.
  // Without a delivery thread: runs under the simulation lock, on whichever thread runs
  // process() (the simulation thread, or a transport thread inside run_or_submit()); must
  // not block. With one (deliver_on_this_thread): runs on that thread only, in the order the
  // outcomes were produced. Must not throw. The outcome is the transport's to read or to
  // move from (the core may reuse the object for the next request).
  virtual void on_service_completion(RequestId id, Outcome&& outcome) = 0;
  // After the table of services changed (register_component, unregister_component): a
  // transport that publishes it (the DDS catalog) publishes it anew. Runs under the
  // simulation lock (or before start()), on whichever thread added or removed the component:
  // it must only post to the transport's own thread, not block. Must not throw. The default does
  // nothing (introspection that reads descriptors() at each call is always current).
  virtual void on_services_changed() {}
  // Delivers a progress report of request `id`, a call submitted with Call::progress, on
  // the thread and in the order on_service_completion would run (so never after the
  // request's final outcome). Must not throw. The default ignores it.
  virtual void on_service_progress(RequestId id, json&& value);

  // ---- the hand-off of outcomes to a transport's own thread ----
  //
  // A transport whose sessions live on one I/O thread calls deliver_on_this_thread() on that
  // thread before it serves anything. From then on:
  //   - an outcome produced on that thread (run_or_submit ran process() there) reaches
  //     on_service_completion at once, after those handed over before it;
  //   - an outcome produced on any other thread (the simulation's) is kept by the core, and
  //     `wake` is called (on the producing thread, under the simulation lock: it must only
  //     post, e.g. asio::post or a DDS guard condition) once per burst: the transport's
  //     thread then calls deliver_handed_over(), which runs on_service_completion for each.
  // A client's replies thus keep the order in which the outcomes were produced, and no
  // transport writes its own cross-thread queue.
  void deliver_on_this_thread(std::function<void()> wake);
  // The delivery thread: delivers every outcome handed over so far, in order; returns how
  // many. Without the simulation lock.
  std::size_t deliver_handed_over();
  // Once the delivery thread has ended (stop()): later outcomes are delivered on whatever
  // thread produces them, as without a delivery thread. Outcomes still handed over stay
  // until deliver_handed_over() (any thread, then) or the destructor.
  void deliver_on_any_thread();
  // Under the simulation lock (a posted task, a cancel's `done`): delivers an outcome the
  // transport made itself, through the same path as the core's.
  void complete_request(RequestId id, Outcome&& outcome);
  // Client `client` (the number its calls carry in Call::client) connected, or left. Any
  // thread; a transport that numbers its clients tells both, once each.
  void client_arrived(std::uint64_t client);
  void client_left(std::uint64_t client);

 private:
  class WorldManager;  // a world's manager (request_manager_worlds.cc)
  class WorldStreams;  // streams() of a transport's manager (request_manager_worlds.cc)
  // streams() after set_streams: the hub itself for a world's manager, else a WorldStreams.
  std::shared_ptr<StreamDirectory> make_streams();
  struct Worlds;  // the worlds attached and the calls sent to them
  // The manager the call's world has, its component's prefix removed ("w0/" too), or null
  // for a world not attached (answered here, as an unknown service); this one for its own.
  // A call sent to a world is remembered (cancel) until its outcome comes back.
  RequestManager* route(RequestId id, Call& call);
  // run_or_submit of calls some of which name worlds: each run of calls of one world goes
  // to its manager, in order.
  bool run_or_submit_across_worlds(std::span<std::pair<RequestId, Call>> calls, bool refilled);
  // run_or_submit of this manager's own calls (no world looked for).
  bool run_or_submit_here(std::span<std::pair<RequestId, Call>> calls, bool refilled);
  // A world's outcome or progress, on its way to this manager's transport.
  void from_world(RequestId id, Outcome&& outcome);
  void progress_from_world(RequestId id, json&& value);
  // The last parts of deliver() and deliver_progress(): to the transport, on its delivery
  // thread.
  void hand_to_transport(RequestId id, Outcome&& outcome);
  void hand_progress_to_transport(RequestId id, json&& value);
  // Whether call `id` went to a world and is not answered yet.
  bool sent_to_world(RequestId id) const;
  bool has_worlds() const { return has_worlds_.load(std::memory_order_acquire); }

  void notify_services_changed();  // on_services_changed(), an exception logged
  // execute(), and with debug logging on (looked at once per request) the time it takes and
  // a log line for its outcome: of a sync request here, of an async one when it ends.
  bool run_request(RequestId id, const Call& call, Outcome& out);
  // Runs one request (on_incoming_request without the copies): true when `out` holds its
  // outcome (sync services and every error), false when an async service started.
  // `started`: when it started, if debug logging is on (the epoch otherwise).
  bool execute(RequestId id, const Call& call, Outcome& out,
               std::chrono::steady_clock::time_point started);
  // execute(), then delivers the outcome if there is one and releases what `call`'s params
  // hold (`refilled`: the transport refills the call object for its next request).
  // `deadline`: when its wait ends (the epoch: never); past it, the call is answered with
  // the timeout without running; an async one started is watched (watch_deadline).
  void execute_and_deliver(RequestId id, Call& call, bool refilled,
                           std::chrono::steady_clock::time_point deadline);
  // ---- deadlines (request_deadlines.cc)
  // Remembers the deadline of async request `id`, just started.
  void watch_deadline(RequestId id, const Call& call,
                      std::chrono::steady_clock::time_point deadline);
  // Ends the async requests whose deadline has passed (under the simulation lock), then
  // asks the gate to wake process() at the next one.
  void expire_deadlines();
  // The timeout outcome of a call of `qualified` ("robot.waypoint.goto") limited to `limit`
  // (`from_call`: its own timeout, else the max wait); `what` ends the message.
  static Outcome timeout_outcome(std::string_view qualified, std::chrono::milliseconds limit,
                                 bool from_call, std::string_view what);
  // Starts an async service; throws what its start method throws.
  // `wants_progress`: the client asked for progress reports (Call::progress).
  void start_async(RequestId id, const Service& service, std::span<const json* const> args,
                   bool wants_progress, std::chrono::steady_clock::time_point started);
  // Starts one call of a concurrent service, outside its component's slot.
  void start_concurrent(RequestId id, const Service& service, std::span<const json* const> args,
                        bool wants_progress, std::chrono::steady_clock::time_point started);
  // The debug log line of an outcome: "Socket service manager: robot.motion set_speed ->
  // SUCCESS in 12 us" (`took`: "in" for sync requests, "after" for async ones).
  void log_outcome(std::string_view component, std::string_view service, const Outcome& outcome,
                   std::chrono::steady_clock::time_point started, std::string_view took) const;
  void interrupt_running(AsyncSlot& slot, Failure reason, std::string message);
  // Runs the Completion::on_interrupt hook of a concurrent call the core has just ended.
  void run_interrupt_hook(detail::CallState& state);
  void execute_cancel(RequestId id, const std::function<void(bool)>& done);
  // Delivers an outcome: on_service_completion here, or handed over to the delivery thread.
  void deliver(RequestId id, Outcome&& outcome);
  // on_service_completion, with what it throws logged.
  void call_completion(RequestId id, Outcome&& outcome);
  // A progress report of a running call: to on_service_progress here, or handed over to
  // the delivery thread, as deliver() does with outcomes; dropped when the call is over.
  void deliver_progress(RequestId id, json&& value);
  // on_service_progress, with what it throws logged.
  void call_progress(RequestId id, json&& value);
  // process() once the lock is held
  std::size_t process_locked();
  std::shared_ptr<AsyncSlot> slot_for(const std::string& component);
  // The service a call names, or null (under the simulation lock). A service found is lent:
  // the caller gives it back with return_service() once the call is over, with `version`
  // (what find_service set). The previous lookup's service is moved out of last_lookup_ and
  // back, so a pipelining client's requests touch no reference count (two atomic operations
  // a request), and a service that unregisters its own component while it runs still lives
  // until it returns.
  std::shared_ptr<Service> find_service(const Call& call, std::uint64_t& version);
  void return_service(std::shared_ptr<Service>&& service, std::uint64_t version) noexcept;
  Outcome unknown_service(const Call& call) const;

  std::string name_;                          // for error messages
  std::shared_ptr<detail::Inbox> inbox_;      // requests, cancels, tasks and completions
  std::unique_ptr<detail::Handoff> handoff_;  // outcomes on their way to the delivery thread
  // the transport's delivery thread (deliver_on_this_thread), or none: written by that
  // thread before it serves anything, read wherever outcomes are produced
  std::atomic<std::thread::id> delivery_thread_{};
  std::shared_ptr<SimulationGate> gate_;   // wake-up and simulation lock, shared with the loop
  std::shared_ptr<StreamHub> stream_hub_;  // the simulation's streams (null: none)
  // what streams() gives: stream_hub_, or for a transport's manager a WorldStreams over it
  // and its worlds' hubs
  std::shared_ptr<StreamDirectory> streams_;
  std::string transport_name_;                   // the configuration's name of this transport
  mutable std::mutex connected_mutex_;           // guards connected_
  std::unordered_set<std::uint64_t> connected_;  // client_arrived and not client_left
  mutable std::mutex table_mutex_;               // guards services_, slots_ and access_
  // component -> service name -> service
  std::unordered_map<std::string, std::unordered_map<std::string, std::shared_ptr<Service>>>
      services_;
  std::unordered_map<std::string, std::shared_ptr<AsyncSlot>> slots_;  // free-function slots
  ServiceAccess access_;                         // which of services_ clients may call (set_access)
  std::atomic<std::uint64_t> table_version_{0};  // bumped by every registration and set_access
  // the previous successful lookup (find_service), valid while table_version_ is unchanged
  // (under the simulation lock)
  struct LastLookup {
    std::string component;             // as the call named it
    std::string name;                  // the service, as the call named it
    std::shared_ptr<Service> service;  // what it found (null while lent: return_service)
    std::uint64_t version = 0;         // table_version_ when it was found
  } last_lookup_;
  // async requests this manager started and has not delivered (under the simulation lock)
  std::unordered_map<RequestId,
                     std::pair<std::shared_ptr<detail::CallState>, std::shared_ptr<AsyncSlot>>>
      running_;
  // the outcome of the request being executed, reused (under the simulation lock)
  Outcome outcome_;
  // written under the simulation lock, read anywhere
  std::atomic<std::uint64_t> requests_handled_{0};
  GlobalPolicy global_policy_ = GlobalPolicy::reject;  // when the running service has no policy
  // set_progress_interval
  std::chrono::nanoseconds progress_interval_ = k_default_progress_interval;
  std::chrono::milliseconds max_wait_{0};  // set_max_wait (zero: none)
  // an async request with a deadline, watched until it passes (under the simulation lock)
  struct Deadline {
    std::chrono::steady_clock::time_point at;  // when it passes
    RequestId id;                              // the request
    std::weak_ptr<detail::CallState> state;    // which request of that id (ids are reused)
    std::chrono::milliseconds limit;           // the limit, for the message
    bool from_call;                            // the call's own timeout, or the max wait
  };
  // a min-heap on `at` (std::push_heap with a greater-than); entries of requests that ended
  // stay until their time, or until a purge when there are many more than running requests
  std::vector<Deadline> deadlines_;
  bool started_ = false;            // start() called (by process() if nobody did; under the lock)
  std::unique_ptr<Worlds> worlds_;  // the worlds it routes to (attach_world); never null
  std::atomic<bool> has_worlds_{false};  // worlds_ holds one: calls are looked at for prefixes
  RequestManager* parent_ = nullptr;     // a world's manager: the transport's it answers to
};

}  // namespace simgate

#endif  // SIMGATE_CORE_REQUEST_MANAGER_H_
