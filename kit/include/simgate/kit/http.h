// simgate/kit/http.h — the HTTP vocabulary the kit's HTTP-speaking framings share: the
// request as Beast parses it, a response as a connection writes it, short plain-text answers,
// and the token a request presents. Used by the WebSocket framing (its upgrade request) and
// the HTTP/1.1 framing (http_connection.h).
#ifndef SIMGATE_KIT_HTTP_H_
#define SIMGATE_KIT_HTTP_H_

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <boost/beast/http/message.hpp>
#include <boost/beast/http/status.hpp>
#include <boost/beast/http/string_body.hpp>

namespace simgate::kit {

using HttpRequest = boost::beast::http::request<boost::beast::http::string_body>;

// An HTTP response (to a plain request, or refusing an upgrade) as the connection writes it.
struct HttpResponse {
  HttpResponse() = default;
  explicit HttpResponse(std::string head) : head(std::move(head)) {}

  std::string head;                         // status line, headers, blank line (and a short body)
  std::shared_ptr<const std::string> body;  // a file's contents (nullptr: none, or in head)
  bool body_cached = false;                 // body is a cache's copy, not this response's own

  // The memory this response holds of its own while it is written (a cached body is held
  // by the cache whatever happens: not counted per response).
  std::size_t own_bytes() const { return head.size() + (body && !body_cached ? body->size() : 0); }
  // The whole response as one text (for tests and logs).
  std::string text() const { return body ? head + *body : head; }
};

// A short plain-text HTTP response that closes the connection (a refusal, a 404 naming what
// the port is), as server `server` ("simgate websocket transport").
std::string plain_http_response(const HttpRequest& request, boost::beast::http::status status,
                                std::string_view body, std::string_view server);

// The whole response a connection refused at accept (TcpListener::Handlers::refusal: too many
// connections) is sent before it closes, the client still sending its request: 503 with
// `body` ("text/plain": `why` and a newline; or a JSON-RPC error's text, `content_type`
// "application/json").
std::string unavailable_response(std::string_view body,
                                 std::string_view content_type = "text/plain; charset=utf-8");

// The value of `request`'s header `name` (case-insensitive), nullopt when absent.
std::optional<std::string_view> header_value(const HttpRequest& request, std::string_view name);

// The token of an `Authorization: Bearer <token>` header; nullopt: none.
std::optional<std::string> bearer_token(const HttpRequest& request);

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_HTTP_H_
