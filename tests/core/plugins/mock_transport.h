// The interface of the mock transport plugin (mock.cc): an in-process "client" that the
// test drives through the plugin object it loaded with dlopen.
#ifndef SIMGATE_TESTS_CORE_MOCK_TRANSPORT_H_
#define SIMGATE_TESTS_CORE_MOCK_TRANSPORT_H_

#include <optional>
#include <string>

#include "simgate/core/request_manager.h"

namespace simgate::testing {

class MockTransport : public RequestManager {
 public:
  using RequestManager::RequestManager;
  // What a client would send; returns the request id.
  virtual RequestId client_call(const std::string& component, const std::string& service,
                                const json& params) = 0;
  // The outcome delivered for `id`, if any.
  virtual std::optional<Outcome> client_outcome(RequestId id) = 0;
  // The options the plugin was created with.
  virtual json options() const = 0;
  virtual bool started() const = 0;
};

}  // namespace simgate::testing

#endif  // SIMGATE_TESTS_CORE_MOCK_TRANSPORT_H_
