// simgate/core/call_context.h — who is calling: the request manager (transport) a running
// service was called through, and so which components that caller may see and act on.
//
// The configuration's mapping (component -> transports) is a boundary: a transport serves
// only the components registered with it. A service whose argument names another component
// (`simulation deactivate robot.motion`) or that describes components (`simulation
// details`) must keep to the caller's side of it, so it needs to know its caller. The core
// tells it without changing any service's signature: while it runs a service for a request
// (a sync call, or an async service's start method), CallContext::current() on that thread
// names the request and its manager; the served set is the manager's own table
// (RequestManager::serves_component), the only source of truth for what a transport serves.
// Within those components, the transport's allow and deny lists (service_access.h) say which
// services its clients may call (RequestManager::may_call): a service that lists services
// (`simulation list_services`, `details`) shows only those.
//
// Life cycle: the core creates one on the stack around each invocation; it is current until
// it is destroyed (nested contexts restore the outer one). Outside a request (a component's
// default_action(), a completion, a host or test calling a service's function directly)
// there is none: current() is null and caller_serves() says yes, the host being trusted
// with everything it built.
//
// Threads: whichever thread runs the service, under the simulation lock; each thread has its
// own current context. A context must not be kept past the call (it lives on the stack).
#ifndef SIMGATE_CORE_CALL_CONTEXT_H_
#define SIMGATE_CORE_CALL_CONTEXT_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "simgate/core/status.h"

namespace simgate {

class RequestManager;

class CallContext {
 public:
  // Makes this the current context of the calling thread until destruction. The core does
  // this around every service it runs; a host may do it to act as a given transport.
  CallContext(const RequestManager& manager, RequestId id, bool raw_attachments = false,
              std::uint64_t client = 0) noexcept;
  ~CallContext();
  CallContext(const CallContext&) = delete;
  CallContext& operator=(const CallContext&) = delete;

  // The context of the request this thread is running a service for, or null.
  static const CallContext* current() noexcept;

  // The manager (transport) the request came through.
  const RequestManager& manager() const noexcept { return manager_; }
  // Its id, as the manager allocated it.
  RequestId request() const noexcept { return id_; }
  // The client it came from (Call::client: a connection's number within its transport;
  // 0 when the transport does not say). manager().client_connected(client()) tells whether
  // it is still there.
  std::uint64_t client() const noexcept { return client_; }
  // Whether the calling transport serves `component` (it was registered with the manager).
  bool serves(const std::string& component) const;
  // Whether the calling transport lets its clients call `component`.`service` (served and
  // allowed by its lists).
  bool may_call(const std::string& component, const std::string& service) const;

  // Whether the caller's transport sends it the attachments raw (Call::raw_attachments):
  // the records may then leave out their encoded copy of them (a camera's PNG), which the
  // transport would drop anyway. A service that does so must attach a payload with a
  // to_json that makes the full record (the transport's fallback when the raw bytes cannot
  // go after all: streams.h).
  bool takes_raw_attachments() const noexcept { return raw_attachments_; }

  // Attaches raw bytes to the result of the sync call running on this thread
  // (Outcome::attachments): the core moves them into its outcome when the service returns.
  // Without a current context (a host calling the function directly) they are dropped.
  static void attach(std::shared_ptr<const StreamPayload> payload);
  // What attach() gave, moved out (the core, after the service returned).
  std::vector<std::shared_ptr<const StreamPayload>> take_attachments() noexcept {
    return std::move(attachments_);
  }

 private:
  const RequestManager& manager_;  // the caller's transport (outlives the call)
  RequestId id_;                   // the request being run
  bool raw_attachments_;           // Call::raw_attachments of the request
  std::uint64_t client_;           // Call::client of the request
  const CallContext* previous_;    // the context this one hides, restored at destruction
  // attach()'s payloads (written through current(), on this thread only)
  mutable std::vector<std::shared_ptr<const StreamPayload>> attachments_;
};

// Hides the calling thread's context until destruction: what runs in its scope runs as
// outside any request. For a service that runs the simulation itself (`simulation step`
// steps the world on the caller's thread): the components' default actions it runs are no
// part of the caller's request, and must see everything as they do on the simulation thread.
class OutsideRequest {
 public:
  OutsideRequest() noexcept;
  ~OutsideRequest();
  OutsideRequest(const OutsideRequest&) = delete;
  OutsideRequest& operator=(const OutsideRequest&) = delete;

 private:
  const CallContext* hidden_;  // the context restored at destruction
};

// Whether the caller of the running service may see and act on `component`: the calling
// transport serves it, or no request is running on this thread (the host itself).
bool caller_serves(const std::string& component);
// Whether the caller of the running service may call `component`.`service` through its
// transport (what introspection shows it), or no request is running on this thread.
bool caller_may_call(const std::string& component, const std::string& service);
// Whether the caller of the running service takes its attachments raw (false outside a request).
bool caller_takes_raw_attachments();
// Who is calling, for a log line: "Socket service manager, request 12", or "the host"
// outside a request.
std::string caller_description();

}  // namespace simgate

#endif  // SIMGATE_CORE_CALL_CONTEXT_H_
