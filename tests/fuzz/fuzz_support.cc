// ServiceHost and its component (fuzz_support.h).
#include "fuzz_support.h"

#include "simgate/core/eigen.h"

namespace simgate::fuzz {

// A component like MORSE's waypoint actuator: async services under each policy, sync ones,
// and an async one that fails with the client's own value (completed(FAILED, {...})).
class Mover : public Component {
 public:
  explicit Mover(std::string name) : Component(std::move(name)) {
    add_async_service("goto", &Mover::go_to, {"x", "y", {"tolerance", 0.5}})
        .interruptible()
        .doc("drive");
    add_async_service("lock", &Mover::lock, {}).noninterruptible();
    add_async_service("wander", &Mover::wander, {{"steps", 3}});  // no local policy
    add_async_service("hold", &Mover::hold, {"value"}).interruptible();
    add_service("position", &Mover::position);
    add_service("teleport", &Mover::teleport, {"to"});
    add_service("fail", &Mover::fail, {"message"});
    add_service("crash", &Mover::crash);
  }
  void go_to(double x, double y, double tolerance) {
    target_ = {x, y};
    tolerance_ = tolerance;
    moving_ = true;
  }
  void lock() {}
  void wander(int steps) { wander_steps_ = steps; }
  void hold(const json& value) { held_ = value; }
  Eigen::Vector2d position() const { return position_; }
  Eigen::Vector3d teleport(const Eigen::Vector3d& to) {
    position_ = to.head<2>();
    return to;
  }
  void fail(const std::string& message) { throw ServiceError(message); }
  int crash() { throw std::out_of_range("index 7 out of range"); }

  // one step of the simulation: what was started finishes
  void default_action() override {
    if (moving_) {
      moving_ = false;
      position_ = target_;
      completed(Status::success, "Arrived");
    }
    if (wander_steps_ > 0 && --wander_steps_ == 0) completed(Status::success);
    if (held_) {
      json value = std::move(*held_);
      held_.reset();
      completed(Status::failed, json{{"held", std::move(value)}});
    }
  }
  // back to the state of a new component (after interrupt(): nothing is running)
  void reset() {
    position_ = target_ = {0, 0};
    tolerance_ = 0;
  }
  void interrupt() override {
    moving_ = false;
    wander_steps_ = 0;
    held_.reset();
    Component::interrupt();
  }

 private:
  Eigen::Vector2d position_{0, 0}, target_{0, 0};
  double tolerance_ = 0;
  bool moving_ = false;
  int wander_steps_ = 0;
  std::optional<json> held_;
};

ServiceHost::ServiceHost()
    : RequestManager("Fuzz service manager"), mover_(std::make_unique<Mover>("robot.mover")) {
  register_component(*mover_);
  // free functions of many signatures (MORSE's register_service)
  register_service("calc", [](double a, double b) { return a + b; }, "add", {"a", "b"});
  register_service("calc",
                   [](const std::vector<double>& v) {
                     double s = 0;
                     for (double x : v) s += x;
                     return s;
                   },
                   "sum", {"values"});
  register_service("calc",
                   [](std::vector<double> v, double k) {
                     for (double& x : v) x *= k;
                     return v;
                   },
                   "scale", {"values", {"factor", 2.0}});
  register_service("text",
                   [](const std::string& name, std::optional<std::string> greeting) {
                     return greeting.value_or("hello") + ", " + name;
                   },
                   "greet", {"name", {"greeting", nullptr}});
  register_service("text", [](const json& value) { return value; }, "echo", {"value"});
  register_service("types",
                   [](std::int8_t a, std::uint8_t b, std::int32_t c, std::uint32_t d,
                      std::int64_t e, std::uint64_t f) { return json{a, b, c, d, e, f}; },
                   "ints", {"a", "b", "c", "d", "e", "f"});
  register_service("types", [](float f, double d) { return json{f, d}; }, "floats", {"f", "d"});
  register_service("types", [](const std::array<double, 3>& p) { return p; }, "point", {"p"});
  register_service("types", [](const std::map<std::string, int>& m) { return m.size(); }, "table",
                   {"entries"});
  register_service("types", [](bool a, bool b) { return a && b; }, "flags", {"a", {"b", false}});
  register_service("types", [](const std::vector<std::vector<int>>& m) { return m; }, "matrix",
                   {"rows"});
  register_service(
      "types", [](const std::optional<std::vector<std::string>>& tags) { return tags.has_value(); },
      "tags", {{"tags", nullptr}});
  register_service("types", [] {}, "none");
  register_service(
      "types",
      [](int a, const std::string& b, const json& c, double d) { return json{a, b, c, d}; },
      "mixed", {"a", "b", "c", {"d", 1.5}});
  // async free functions: the completion is kept and finished by tick() (MORSE's
  // result_setter), one per component or, concurrent, any number
  register_async_service("jobs",
                         [this](Completion done, int start) {
                           jobs_.push_back({std::move(done), json(std::int64_t{start} + 1)});
                         },
                         "compute", {"start"});
  register_async_service("jobs",
                         [this](Completion done, double seconds) {
                           jobs_.push_back({std::move(done), json(seconds)});
                         },
                         "wait", {"seconds"})
      .concurrent();
  register_async_service("jobs",
                         [](Completion done, const json& value) {
                           done(Status::success, value);  // finished before it returns
                         },
                         "instant", {"value"});
}

ServiceHost::~ServiceHost() {
  // every request ends once: still running ones end now (Failure::shutdown)
  abandon_pending("the fuzz input ended");
  for (auto& [id, count] : async_) FUZZ_CHECK(count == 1, "an async request ended exactly once");
}

ServiceHost& ServiceHost::instance() {
  static ServiceHost* host = new ServiceHost;  // reachable: not a leak
  return *host;
}

void ServiceHost::end_input() {
  for (RequestId id : started_) cancel(id);  // those that ended are not found
  {
    std::lock_guard lock(*gate());
    for (auto& [done, result] : jobs_)
      done(Status::success, std::move(result));  // no-op when cancelled
    jobs_.clear();
  }
  process();
  for (auto& [id, count] : async_)
    FUZZ_CHECK(count == 1, "an async request ended exactly once (" + std::to_string(count) + ")");
  async_.clear();
  started_.clear();
  set_global_policy(GlobalPolicy::reject);
  FUZZ_CHECK(!mover_->has_running_request(), "nothing runs after end_input");
  mover_->reset();
}

std::optional<Outcome> ServiceHost::call(const std::string& component, const std::string& service,
                                         const json& params) {
  const RequestId id = new_request_id();
  std::optional<Outcome> outcome;
  {
    std::lock_guard lock(*gate());
    outcome = on_incoming_request(id, Call{component, service, params});
  }
  if (outcome) {
    check_outcome(*outcome);
  } else {
    std::lock_guard lock(mutex_);
    async_.emplace(id, 0);
    started_.push_back(id);
  }
  return outcome;
}

void ServiceHost::tick() {
  {
    std::lock_guard lock(*gate());
    mover_->default_action();
    for (auto& [done, result] : jobs_) done(Status::success, std::move(result));
    jobs_.clear();
  }
  process();
}

void ServiceHost::cancel_started(std::size_t n) {
  if (started_.empty()) return;
  cancel(started_[n % started_.size()]);
  process();
}

void ServiceHost::on_service_completion(RequestId id, Outcome&& outcome) {
  check_outcome(outcome);
  std::lock_guard lock(mutex_);
  auto it = async_.find(id);
  FUZZ_CHECK(it != async_.end(), "a completion is for an async request of this manager");
  ++it->second;
}

}  // namespace simgate::fuzz
