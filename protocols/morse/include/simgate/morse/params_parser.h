// simgate/morse/params_parser.h — the socket transport's parser for the parameters of a request
// line.
//
// MORSE's text protocol carries the parameters as the rest of the line after the service
// name. Today's MORSE sends JSON (`[1, 2]`); its documentation and older clients send
// Python literals (`(1,2)`, `(5,)`, `['a', True, None]`). parse_params() accepts both with
// one small recursive-descent parser that never evaluates anything:
//
//   value  := number | string | True | False | None | true | false | null
//           | NaN | Infinity | -Infinity
//           | '[' items ']' | '(' items ')' | '{' key ':' value, ... '}'
//   items  := value (',' value)* ','?      (trailing comma allowed, `(5,)` is a tuple)
//   string := '...' | "..." with \n \t \r \b \f \v \a \0 \\ \' \" \/ \xHH \uHHHH \UHHHHHHHH
//
// Tuples and lists both become JSON arrays. Unlike Python, parentheses always make a
// tuple: `(5)` is the one-element tuple `[5]`, which is what a caller writing a parameter
// list means. Dictionary keys must be strings. Nesting is limited (k_max_depth) so a
// hostile line cannot exhaust the stack.
//
// Threads: pure functions, callable from any thread.
#ifndef SIMGATE_MORSE_PARAMS_PARSER_H_
#define SIMGATE_MORSE_PARAMS_PARSER_H_

#include <cstddef>
#include <string>
#include <string_view>

#include "simgate/core/status.h"

namespace simgate::socket {

// Deepest nesting of lists, tuples and dicts accepted.
inline constexpr std::size_t k_max_depth = 64;

// The result of parse_params(): either `value`, or `error` with the column it refers to.
struct ParamsParse {
  bool ok = false;         // true when `value` holds the parsed parameters
  json value;              // the parameters (null when the text is empty)
  std::string error;       // what was wrong, e.g. "expected ',' or ')' but found 'x'"
  std::size_t column = 0;  // 1-based column of the error, counted from `first_column`
  // when the text is a sequence of bare values (`0.5 0.2`, `0.5, 0.2`), the list the user
  // meant, written as MORSE writes JSON ("[0.5, 0.2]"); empty otherwise
  std::string example;
};

// Parses `text` (the parameters of one request line, surrounding blanks allowed). An
// empty or all-blank text gives a null value (call with no arguments). Several bare values
// (`set_speed 0.5 0.2`) are a syntax error whose `example` is the list meant. `first_column` is
// the column of text[0] in the whole line, so errors point into the line the client sent.
ParamsParse parse_params(std::string_view text, std::size_t first_column = 1);

// The same into `value`, for a caller that reuses it from request to request: parameters
// that are a list or a tuple refill the array `value` holds (its capacity is kept: no
// allocation). On a syntax error returns false and fills `error`'s error and column
// (`value` is then unspecified).
bool parse_params_into(std::string_view text, std::size_t first_column, json& value,
                       ParamsParse& error);

}  // namespace simgate::socket

#endif  // SIMGATE_MORSE_PARAMS_PARSER_H_
