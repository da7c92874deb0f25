// deployment_mapping.cc — which transports serve a component and carry its stream
// (Deployment::transports_for, streams_for, stream_frequency_for): its exact name, else the
// most specific matching glob, else "default"; a pseudo-component streams only when a rule
// names it exactly. The rules are read and checked by parse_deployment (deployment.cc).
#include <algorithm>

#include "deployment_parsing.h"
#include "simgate/gateway/deployment.h"

namespace simgate::gateway {

namespace {

std::size_t literal_chars(const std::string& pattern) {
  return static_cast<std::size_t>(std::count_if(pattern.begin(), pattern.end(), [](char c) {
    return c != '*' && c != '?' && c != '[' && c != ']';
  }));
}

// The rule of `rules` that gives `component` its transports: its exact name, else the most
// specific matching glob (most literal characters; ties: first in key order); null when none
// does (the caller's fallback, "default", applies).
const ServiceRule* best_rule(const std::vector<ServiceRule>& rules, const std::string& component) {
  for (const auto& r : rules)
    if (!is_glob(r.pattern) && r.pattern == component) return &r;
  const ServiceRule* best = nullptr;
  for (const auto& r : rules)
    if (is_glob(r.pattern) && glob_matches(r.pattern, component) &&
        (!best || literal_chars(r.pattern) > literal_chars(best->pattern)))
      best = &r;
  return best;
}

// The transports `rules` give `component` (best_rule), else `fallback`.
std::vector<std::string> match_rules(const std::vector<ServiceRule>& rules,
                                     const std::optional<std::vector<std::string>>& fallback,
                                     const std::string& component) {
  if (const ServiceRule* r = best_rule(rules, component)) return r->transports;
  return fallback.value_or(std::vector<std::string>{});
}

bool is_pseudo_component(const std::string& name) {
  return std::find(k_pseudo_components.begin(), k_pseudo_components.end(), name) !=
             k_pseudo_components.end() ||
         std::find(k_stream_only_components.begin(), k_stream_only_components.end(), name) !=
             k_stream_only_components.end();
}

}  // namespace

std::vector<std::string> Deployment::transports_for(const std::string& component) const {
  if (!has_services) {
    std::vector<std::string> all;
    for (const auto& t : transports) all.push_back(t.name);
    return all;
  }
  // communication goes with simulation unless named (MORSE serves both on every socket)
  if (component == "communication" &&
      std::none_of(rules.begin(), rules.end(),
                   [](const ServiceRule& r) { return r.pattern == "communication"; }))
    return transports_for("simulation");
  return match_rules(rules, default_transports, component);
}

std::vector<std::string> Deployment::streams_for(const std::string& component) const {
  // a pseudo-component streams only when named (see the header)
  if (is_pseudo_component(component)) {
    const ServiceRule* r = stream_rule_named(component);
    return r ? r->transports : std::vector<std::string>{};
  }
  return match_rules(stream_rules, default_stream_transports, component);
}

std::optional<double> Deployment::stream_frequency_for(const std::string& component) const {
  if (is_pseudo_component(component)) {
    const ServiceRule* r = stream_rule_named(component);
    return r ? r->frequency : std::nullopt;
  }
  if (const ServiceRule* r = best_rule(stream_rules, component)) return r->frequency;
  return default_stream_transports ? default_stream_frequency : std::nullopt;
}

const ServiceRule* Deployment::stream_rule_named(const std::string& component) const {
  for (const auto& r : stream_rules)
    if (r.pattern == component) return &r;
  return nullptr;
}

}  // namespace simgate::gateway
