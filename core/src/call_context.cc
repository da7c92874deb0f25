#include "simgate/core/call_context.h"

#include "simgate/core/request_manager.h"

namespace simgate {

namespace {
// The innermost context of this thread (see call_context.h); null outside a request.
thread_local const CallContext* t_current = nullptr;
}  // namespace

CallContext::CallContext(const RequestManager& manager, RequestId id, bool raw_attachments,
                         std::uint64_t client) noexcept
    : manager_(manager),
      id_(id),
      raw_attachments_(raw_attachments),
      client_(client),
      previous_(t_current) {
  t_current = this;
}

CallContext::~CallContext() { t_current = previous_; }

const CallContext* CallContext::current() noexcept { return t_current; }

void CallContext::attach(std::shared_ptr<const StreamPayload> payload) {
  if (t_current && payload) t_current->attachments_.push_back(std::move(payload));
}

OutsideRequest::OutsideRequest() noexcept : hidden_(t_current) { t_current = nullptr; }

OutsideRequest::~OutsideRequest() { t_current = hidden_; }

bool CallContext::serves(const std::string& component) const {
  return manager_.serves_component(component);
}

bool CallContext::may_call(const std::string& component, const std::string& service) const {
  return manager_.may_call(component, service);
}

bool caller_serves(const std::string& component) {
  const CallContext* context = CallContext::current();
  return !context || context->serves(component);
}

bool caller_may_call(const std::string& component, const std::string& service) {
  const CallContext* context = CallContext::current();
  return !context || context->may_call(component, service);
}

bool caller_takes_raw_attachments() {
  const CallContext* context = CallContext::current();
  return context && context->takes_raw_attachments();
}

std::string caller_description() {
  const CallContext* context = CallContext::current();
  if (!context) return "the host";
  return context->manager().name() + ", request " + std::to_string(context->request());
}

}  // namespace simgate
