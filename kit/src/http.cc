#include "simgate/kit/http.h"

#include <sstream>

#include <boost/beast/http/write.hpp>

namespace simgate::kit {

namespace http = boost::beast::http;

std::string plain_http_response(const HttpRequest& request, http::status status,
                                std::string_view body, std::string_view server) {
  http::response<http::string_body> response{status, request.version()};
  response.set(http::field::server, boost::beast::string_view(server.data(), server.size()));
  response.set(http::field::content_type, "text/plain; charset=utf-8");
  response.keep_alive(false);
  response.body() = body;
  response.prepare_payload();
  std::ostringstream out;
  out << response;
  return out.str();
}

std::string unavailable_response(std::string_view body, std::string_view content_type) {
  std::string out = "HTTP/1.1 503 Service Unavailable\r\nContent-Type: ";
  out += content_type;
  out += "\r\nContent-Length: ";
  out += std::to_string(body.size());
  out += "\r\nConnection: close\r\n\r\n";
  out += body;
  return out;
}

std::optional<std::string_view> header_value(const HttpRequest& request, std::string_view name) {
  auto it = request.find(boost::beast::string_view(name.data(), name.size()));
  if (it == request.end()) return std::nullopt;
  return std::string_view(it->value().data(), it->value().size());
}

std::optional<std::string> bearer_token(const HttpRequest& request) {
  const std::optional<std::string_view> value = header_value(request, "Authorization");
  constexpr std::string_view k_bearer = "Bearer ";
  if (value && value->size() > k_bearer.size() && value->substr(0, k_bearer.size()) == k_bearer)
    return std::string(value->substr(k_bearer.size()));
  return std::nullopt;
}

}  // namespace simgate::kit
