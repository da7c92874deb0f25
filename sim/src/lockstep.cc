// The lockstep barrier of `simulation` (stepping.h, docs/world/stepping.md "Lockstep"):
// several clients step one paused simulation together; it advances when every participant
// has asked, as CoppeliaSim's synchronous clients do.
#include <algorithm>
#include <chrono>
#include <utility>

#include "simgate/core/errors.h"
#include "helpers.h"
#include "stepping.h"

namespace simgate::sim {

namespace {

// A participant's name is echoed in messages and in get_simulation_state: short and printable.
constexpr std::size_t k_max_name_length = 64;

}  // namespace

Lockstep::Lockstep(Simulation& sim, std::function<void(const char* why)> stop_plain_step)
    : sim_(sim), stop_plain_step_(std::move(stop_plain_step)) {}

void Lockstep::join(Completion call, const std::string& participant) {
  prune();
  std::string name = participant;
  if (name.empty()) {
    do name = "p" + std::to_string(next_number_++);
    while (find(name));
  } else {
    const bool printable =
        std::all_of(name.begin(), name.end(), [](char c) { return c > ' ' && c < 127; });
    if (name.size() > k_max_name_length || !printable)
      throw ServiceError("simulation lockstep_join: participant = \"" +
                             name.substr(0, k_max_name_length) + "\": expected up to " +
                             std::to_string(k_max_name_length) +
                             " printable characters without spaces (or nothing: a name is made up)",
                         Failure::bad_arguments, {{"parameter", "participant"}});
    if (find(name))
      throw ServiceError("simulation lockstep_join: participant '" + name +
                             "' is already in the lockstep "
                             "(participants: " +
                             names_text() + "); choose another name, or none (one is made up)",
                         Failure::bad_arguments, {{"parameter", "participant"}});
  }
  // from now on the participants drive the steps
  stop_plain_step_("simulation lockstep_join: the simulation is stepped in lockstep from now on");
  // a participant who leaves may release the barrier the others wait at, paused or not:
  // told at once, not at the next step (there may be none)
  call.on_interrupt([weak = weak_from_this()] {
    if (auto self = weak.lock()) {
      self->prune();
      self->release_if_complete(/*inline_steps=*/false);
    }
  });
  participants_.push_back({name, call, Completion()});
  call.progress(json{{"participant", name}, {"participants", names()}});
}

void Lockstep::step(Completion call, const std::string& participant, std::int64_t n) {
  check_step_count("simulation lockstep_step", n);
  check_paused("simulation lockstep_step", sim_);
  prune();
  Participant* p = find(participant);
  if (!p)
    throw ServiceError("simulation lockstep_step: participant = \"" +
                           participant.substr(0, k_max_name_length) +
                           "\" is not in the lockstep (participants: " + names_text() +
                           "); join first with simulation lockstep_join",
                       Failure::bad_arguments, {{"parameter", "participant"}});
  if (p->asked)
    throw ServiceError("simulation lockstep_step: participant '" + p->name +
                           "' already waits at the barrier; one ask per participant and barrier",
                       Failure::service_error, {{"parameter", "participant"}});
  if (gathering_n_ != 0 && static_cast<std::uint64_t>(n) != gathering_n_)
    throw ServiceError("simulation lockstep_step: n = " + std::to_string(n) +
                           ", but the barrier waits for n = " + std::to_string(gathering_n_) +
                           " (asked by " + simgate::join(waiting_names()) +
                           "): every participant asks for the same steps",
                       Failure::bad_arguments, {{"parameter", "n"}, {"expected", gathering_n_}});
  p->asked = std::move(call);
  gathering_n_ = static_cast<std::uint64_t>(n);
  release_if_complete(/*inline_steps=*/true);
}

bool Lockstep::refuses_plain_steps(const char* service, std::string& why) {
  prune();
  if (!participants_.empty()) {
    why =
        std::string(service) +
        ": the simulation is stepped in lockstep (participants: " + names_text() +
        "); a participant asks with simulation lockstep_step, the others leave by cancelling their "
        "simulation lockstep_join";
    return true;
  }
  if (stepping_) {
    why = std::string(service) + ": the last lockstep barrier's steps are still being taken (" +
          std::to_string(sim_.owed_steps()) + " left); ask again once they are";
    return true;
  }
  return false;
}

void Lockstep::stop_steps(const char* why) {
  if (!stepping_) return;
  stepping_ = false;
  const std::uint64_t left = sim_.forgive_owed_steps();
  preempt(released_, why, released_n_ - left, released_n_);
}

void Lockstep::stop_all(const char* why) {
  stop_steps(why);
  std::vector<Completion> gathering;
  for (Participant& p : participants_)
    if (p.asked) gathering.push_back(std::exchange(p.asked, Completion()));
  preempt(gathering, why, 0, gathering_n_);
  gathering_n_ = 0;
}

json Lockstep::state() {
  prune();
  return {{"participants", names()},
          {"waiting", waiting_names()},
          {"n", gathering_n_ == 0 ? json(nullptr) : json(gathering_n_)},
          {"stepping", stepping_}};
}

void Lockstep::prune() {
  // a released barrier whose steps were forgiven elsewhere (a divergence, which also ended
  // its calls): the last step taken would have cleared stepping_ at once
  if (stepping_ && sim_.owed_steps() == 0) {
    stepping_ = false;
    preempt(released_, "the lockstep's steps were stopped", 0, released_n_);
  }
  std::vector<Completion> orphans;
  std::erase_if(participants_, [&](Participant& p) {
    if (p.asked.done()) p.asked = Completion();  // cancelled, timed out, ended by a divergence
    if (!p.membership.done()) return false;
    if (p.asked) orphans.push_back(p.asked);
    return true;
  });
  for (const Completion& call : orphans) {
    Outcome o;
    o.status = Status::preempted;
    o.failure = Failure::preempted;
    o.message =
        "simulation lockstep_step: its participant left the lockstep (its lockstep_join ended)";
    call.finish(std::move(o));
  }
  if (waiting_names().empty()) gathering_n_ = 0;
}

void Lockstep::release_if_complete(bool inline_steps) {
  if (stepping_ || participants_.empty() || !sim_.paused()) return;
  for (const Participant& p : participants_)
    if (!p.asked) return;
  released_.clear();
  for (Participant& p : participants_) released_.push_back(std::exchange(p.asked, Completion()));
  released_n_ = std::exchange(gathering_n_, 0);
  stepping_ = true;
  sim_.owe_steps(released_n_, [this] { released_steps_done(); });
  if (inline_steps)
    sim_.take_owed_steps(std::chrono::steady_clock::now() + Simulation::k_inline_step_budget);
  else
    sim_.gate()->signal();  // the loop takes them (it may be asleep, paused)
}

void Lockstep::released_steps_done() {
  stepping_ = false;
  const json result{{"sim_time", sim_.sim_time()}, {"steps_done", released_n_}};
  for (const Completion& call : std::exchange(released_, {})) call(Status::success, result);
  // asks that arrived meanwhile may make the next barrier complete: its steps are the loop's
  // (this runs inside the last step's take_owed_steps)
  release_if_complete(/*inline_steps=*/false);
}

void Lockstep::preempt(std::vector<Completion>& calls, const char* why, std::uint64_t steps_done,
                       std::uint64_t n) {
  for (const Completion& call : std::exchange(calls, {})) {
    Outcome o;
    o.status = Status::preempted;
    o.failure = Failure::preempted;
    o.message = why;
    o.value =
        json{{"sim_time", sim_.sim_time()}, {"steps_done", steps_done}, {"steps_requested", n}};
    call.finish(std::move(o));
  }
}

Lockstep::Participant* Lockstep::find(const std::string& name) {
  for (Participant& p : participants_)
    if (p.name == name) return &p;
  return nullptr;
}

std::vector<std::string> Lockstep::names() const {
  std::vector<std::string> out;
  for (const Participant& p : participants_) out.push_back(p.name);
  return out;
}

std::vector<std::string> Lockstep::waiting_names() const {
  std::vector<std::string> out;
  for (const Participant& p : participants_)
    if (p.asked) out.push_back(p.name);
  return out;
}

std::string Lockstep::names_text() const {
  return participants_.empty() ? "none" : simgate::join(names());
}

}  // namespace simgate::sim
