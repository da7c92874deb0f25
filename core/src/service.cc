#include "simgate/core/service.h"

#include <algorithm>
#include <set>

namespace simgate {

std::string_view to_string(Policy policy) noexcept {
  switch (policy) {
    case Policy::unspecified: return "unspecified";
    case Policy::interruptible: return "interruptible";
    case Policy::noninterruptible: return "noninterruptible";
  }
  return "unspecified";
}

// ---- descriptors

std::size_t ServiceDescriptor::required_count() const {
  return static_cast<std::size_t>(
      std::count_if(params.begin(), params.end(), [](const auto& p) { return !p.default_value; }));
}

std::string ServiceDescriptor::signature() const {
  std::string out;
  for (const auto& p : params) {
    if (!out.empty()) out += ", ";
    out += p.name;
    if (p.default_value) out += "=" + p.default_value->dump();
  }
  return out;
}

json ServiceDescriptor::params_schema() const {
  json properties = json::object();
  json required = json::array();
  for (const ParamDescriptor& p : params) {
    json schema = p.schema.is_object() ? p.schema : json::object();
    if (p.default_value)
      schema["default"] = *p.default_value;
    else
      required.push_back(p.name);
    properties[p.name] = std::move(schema);
  }
  json out{{"type", "object"}, {"properties", std::move(properties)}};
  if (!required.empty()) out["required"] = std::move(required);
  if (!doc.empty()) out["description"] = doc;
  return out;
}

json ServiceDescriptor::to_json() const {
  json ps = json::array();
  for (const auto& p : params) {
    json e{
        {"name", p.name}, {"schema", p.schema}, {"type", p.type}, {"required", !p.default_value}};
    if (p.default_value) e["default"] = *p.default_value;
    ps.push_back(std::move(e));
  }
  json out{{"component", component}, {"name", name}, {"async", is_async},
           {"params", ps},           {"doc", doc},   {"result", result_schema}};
  if (is_async) {
    out["policy"] = std::string(to_string(policy));
    out["concurrent"] = concurrent;
  }
  if (process_wide) out["process_wide"] = true;
  return out;
}

// ---- completion

bool Completion::operator()(Status status, json result) const {
  Outcome o;
  o.status = status;
  if (!result.is_null()) o.value = std::move(result);
  if (status == Status::failed) {
    o.failure = Failure::service_error;
    o.message = o.value ? (o.value->is_string() ? o.value->get<std::string>() : o.value->dump())
                        : "the service failed";
  } else if (status == Status::preempted && state_) {
    o.failure = state_->interrupt_reason;
    o.message = state_->interrupt_message.empty() ? "preempted" : state_->interrupt_message;
  }
  return finish(std::move(o));
}

bool Completion::finish(Outcome outcome) const {
  if (!state_ || state_->finished.exchange(true)) return false;
  if (state_->timed_out.load(std::memory_order_acquire)) [[unlikely]]
    // its deadline passed: the reply is the timeout, whatever the component says now
    outcome = Outcome::failed(Failure::timeout, state_->interrupt_message, state_->timeout_data);
  if (auto sink = state_->sink.lock()) sink->finished(state_->id, std::move(outcome));
  return true;
}

void Completion::on_interrupt(std::function<void()> hook) const {
  if (state_) state_->on_interrupt = std::move(hook);
}

namespace {
std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
bool interval_passed(std::int64_t last, std::int64_t now, std::chrono::nanoseconds interval) {
  return last == std::numeric_limits<std::int64_t>::min() || now - last >= interval.count();
}
}  // namespace

bool Completion::progress_due() const {
  return state_ && state_->progress_interval.count() >= 0 && !state_->finished.load() &&
         interval_passed(state_->last_progress_ns.load(std::memory_order_relaxed), steady_now_ns(),
                         state_->progress_interval);
}

bool Completion::progress(json value) const {
  if (!state_ || state_->progress_interval.count() < 0 || state_->finished.load()) return false;
  const std::int64_t now = steady_now_ns();
  std::int64_t last = state_->last_progress_ns.load(std::memory_order_relaxed);
  // one report per interval, whichever thread reports
  if (!interval_passed(last, now, state_->progress_interval)) return false;
  if (!state_->last_progress_ns.compare_exchange_strong(last, now, std::memory_order_relaxed))
    return false;
  if (auto sink = state_->sink.lock()) sink->progressed(state_->id, std::move(value));
  return true;
}

std::vector<Completion> AsyncSlot::running_concurrent() const {
  std::vector<Completion> out;
  for (const auto& state : concurrent)
    if (!state->finished.load()) out.emplace_back(state);
  return out;
}

// ---- builder

ServiceBuilder& ServiceBuilder::doc(std::string text) {
  service_->descriptor().doc = std::move(text);
  return *this;
}

namespace {
void set_policy(ServiceDescriptor& d, Policy policy) {
  if (!d.is_async)
    detail::throw_registration_error(d.qualified_name() +
                                     ": only async services have an interruption policy");
  if (d.concurrent)
    detail::throw_registration_error(
        d.qualified_name() +
        ": a concurrent service has no interruption policy (its calls never meet)");
  d.policy = policy;
}
}  // namespace

ServiceBuilder& ServiceBuilder::interruptible() {
  set_policy(service_->descriptor(), Policy::interruptible);
  return *this;
}

ServiceBuilder& ServiceBuilder::noninterruptible() {
  set_policy(service_->descriptor(), Policy::noninterruptible);
  return *this;
}

ServiceBuilder& ServiceBuilder::process_wide() {
  service_->descriptor().process_wide = true;
  service_->descriptor().replayed = false;  // the world does not see it
  return *this;
}

ServiceBuilder& ServiceBuilder::not_replayed() {
  service_->descriptor().replayed = false;
  return *this;
}

ServiceBuilder& ServiceBuilder::concurrent() {
  ServiceDescriptor& d = service_->descriptor();
  if (!d.is_async)
    detail::throw_registration_error(d.qualified_name() +
                                     ": only async services can be concurrent");
  if (!service_->takes_completion())
    detail::throw_registration_error(
        d.qualified_name() +
        ": a concurrent service takes its call's Completion as first parameter");
  if (d.policy != Policy::unspecified)
    detail::throw_registration_error(
        d.qualified_name() +
        ": a concurrent service has no interruption policy (its calls never meet)");
  d.concurrent = true;
  return *this;
}

ServiceBuilder& ServiceBuilder::result_schema(json schema) {
  service_->descriptor().result_schema = std::move(schema);
  return *this;
}

const ServiceDescriptor& ServiceBuilder::descriptor() const { return service_->descriptor(); }

// ---- argument binding

namespace {

std::string expected_count(const ServiceDescriptor& d) {
  std::size_t required = d.required_count(), total = d.params.size();
  std::string n = required == total ? std::to_string(total)
                                    : std::to_string(required) + " to " + std::to_string(total);
  return n + (total ? " (" + d.signature() + ")" : "");
}

json error_data(const ServiceDescriptor& d) {
  return json{{"component", d.component}, {"service", d.name}, {"expected", d.signature()}};
}

// Too few or too many parameters, in MORSE's words (core/request_manager.py): "parameters
// expected for service ...!" when none came at all, which pymorse raises as
// MorseServiceFailed; "wrong # of parameters for service ..." otherwise, which it raises as
// TypeError. `missing`: the required parameters not given ("'a', 'b'"), or empty.
[[noreturn]] void throw_arity(const ServiceDescriptor& d, std::size_t given,
                              const std::string& missing) {
  const std::string expected = "expected " + expected_count(d) + ", got " + std::to_string(given) +
                               (missing.empty() ? "" : " (missing " + missing + ")");
  if (given == 0)
    throw WrongArguments("parameters expected for service " + d.qualified_name() + "! " + expected,
                         error_data(d));
  throw WrongArguments("wrong # of parameters for service " + d.qualified_name() + ": " + expected,
                       error_data(d));
}

}  // namespace

BoundArguments bind_arguments(const ServiceDescriptor& d, const json& params) {
  const std::size_t total = d.params.size();
  BoundArguments args(total);

  // the usual call: every parameter given, in order
  if (params.is_array() && params.size() == total) {
    const auto& given = params.get_ref<const json::array_t&>();
    for (std::size_t i = 0; i < total; ++i) args[i] = &given[i];
    return args;
  }

  if (params.is_null()) {
    // no arguments at all
  } else if (params.is_array()) {
    if (params.size() > total || params.size() < d.required_count())
      throw_arity(d, params.size(), "");
    for (std::size_t i = 0; i < params.size(); ++i) args[i] = &params[i];
  } else if (params.is_object()) {
    for (auto it = params.begin(); it != params.end(); ++it) {
      auto p = std::find_if(d.params.begin(), d.params.end(),
                            [&](const ParamDescriptor& pd) { return pd.name == it.key(); });
      if (p == d.params.end()) {
        json data = error_data(d);
        data["parameter"] = it.key();
        throw WrongArguments("wrong parameter for service " + d.qualified_name() +
                                 ": no parameter named '" + it.key() +
                                 "' (parameters: " + (total ? d.signature() : "none") + ")",
                             data);
      }
      args[std::size_t(p - d.params.begin())] = &it.value();
    }
  } else {
    throw WrongArguments("wrong parameters for service " + d.qualified_name() +
                             ": parameters must be a list (positional) or an object (named), not " +
                             describe_json(params),
                         error_data(d));
  }

  // defaults for the rest; a required one missing is an arity error
  std::string missing;
  for (std::size_t i = 0; i < total; ++i) {
    if (args[i]) continue;
    if (d.params[i].default_value)
      args[i] = &*d.params[i].default_value;
    else
      missing += (missing.empty() ? "'" : ", '") + d.params[i].name + "'";
  }
  if (!missing.empty()) throw_arity(d, params.is_null() ? 0 : params.size(), missing);
  return args;
}

namespace detail {

void throw_type_mismatch(const ServiceDescriptor& d, std::size_t index, const TypeMismatch& m) {
  const std::string& name = d.params[index].name;
  json data{{"component", d.component},
            {"service", d.name},
            {"parameter", name},
            {"expected", m.expected}};
  throw WrongArguments("wrong parameter type for service " + d.qualified_name() + ": parameter '" +
                           name + m.where + "' expects " + m.expected + ", got " + m.found,
                       data);
}

void throw_registration_error(const std::string& what) {
  throw std::logic_error("service registration: " + what);
}

void name_parameters(ServiceDescriptor& d, std::vector<ParamDescriptor> typed,
                     std::vector<Param> names) {
  if (!names.empty() && names.size() != typed.size())
    throw_registration_error(d.qualified_name() + ": " + std::to_string(names.size()) +
                             " parameter names given for " + std::to_string(typed.size()) +
                             " parameters");
  std::set<std::string> seen;
  bool defaults_started = false;
  for (std::size_t i = 0; i < typed.size(); ++i) {
    typed[i].name = names.empty() ? "arg" + std::to_string(i) : names[i].name;
    if (!names.empty()) typed[i].default_value = names[i].default_value;
    if (typed[i].name.empty() || !seen.insert(typed[i].name).second)
      throw_registration_error(d.qualified_name() +
                               ": parameter names must be unique and non-empty");
    if (typed[i].default_value)
      defaults_started = true;
    else if (defaults_started)
      throw_registration_error(d.qualified_name() + ": parameter '" + typed[i].name +
                               "' without a default follows one with a default");
  }
  d.params = std::move(typed);
}

}  // namespace detail
}  // namespace simgate
