#include "cyclone_config.h"

#include <dds/ddsrt/xmlparser.h>

#include <cctype>
#include <cstring>
#include <vector>

#include "dds_support.h"
#include "simgate/core/errors.h"
#include "simgate/core/suggest.h"

namespace simgate::dds {

// Cyclone's setting names (generated from its ddsi_cfgelems.h: cyclone_settings.cc.in).
extern const std::vector<std::string> k_cyclone_setting_names;

namespace {

// An interface name no machine has (longer than IFNAMSIZ allows): Cyclone fails its
// interface lookup on it, after reading and checking every setting and before it opens a
// socket.
constexpr const char* k_absent_interface = "simgate-settings-check";

// Appended to the settings under test: the interface above, listed after the settings' own
// interfaces (Cyclone checks those first, in order), and tracing sent to stderr (a trace
// file the settings name is opened before the interface lookup; stderr output goes to a
// sink that drops it).
const std::string k_stop_before_sockets =
    std::string("<CycloneDDS><Domain Id=\"any\"><General><Interfaces><NetworkInterface name=\"") +
    k_absent_interface +
    "\" "
    "presence_required=\"true\"/></Interfaces></General><Tracing><OutputFile>stderr</OutputFile></"
    "Tracing>"
    "</Domain></CycloneDDS>";

// Counts the elements left open at the end of the parse (ddsrt_xmlp callbacks).
struct Depth {
  std::size_t open = 0;  // elements opened and not closed
  bool failed = false;   // the parser reported an error
};

int on_open(void* varg, uintptr_t, uintptr_t*, const char*, int) {
  ++static_cast<Depth*>(varg)->open;
  return 0;
}
int on_close(void* varg, uintptr_t, int) {
  auto& depth = *static_cast<Depth*>(varg);
  if (depth.open > 0) --depth.open;
  return 0;
}
void on_error(void* varg, const char*, int) { static_cast<Depth*>(varg)->failed = true; }

// Parses `xml` with Cyclone's parser and `options`: how many elements were left open when
// it stopped, whether it failed, and how many bytes it read.
Depth parse(const char* xml, unsigned options, std::size_t* used = nullptr) {
  Depth depth;
  ddsrt_xmlp_callbacks callbacks{};
  callbacks.elem_open = &on_open;
  callbacks.elem_close = &on_close;
  callbacks.error = &on_error;
  ddsrt_xmlp_state* parser = ddsrt_xmlp_new_string(xml, &depth, &callbacks);
  ddsrt_xmlp_set_options(parser, options);
  if (ddsrt_xmlp_parse(parser) < 0) depth.failed = true;
  if (used) *used = ddsrt_xmlp_get_bufpos(parser);
  ddsrt_xmlp_free(parser);
  return depth;
}

// The closing tags `settings` lacks at its end. Cyclone reads an XML fragment of the
// settings text up to its top-level closing tag or, missing one, to the end of the text
// (ddsi_config_init: DDSRT_XMLP_MISSING_CLOSE_AS_EOF): what is appended to such settings
// would be read inside their last element unless it is closed first.
std::string missing_closing_tags(const std::string& settings) {
  auto separator = [](char c) { return std::isspace(static_cast<unsigned char>(c)) || c == ','; };
  std::size_t cursor = 0;
  while (cursor < settings.size()) {
    while (cursor < settings.size() && separator(settings[cursor])) ++cursor;
    if (cursor == settings.size()) break;
    if (settings[cursor] != '<') {
      // a file name or URI, up to the next comma: Cyclone reads the file whole
      std::size_t comma = settings.find(',', cursor);
      if (comma == std::string::npos) break;
      cursor = comma + 1;
      continue;
    }
    // as Cyclone reads it
    std::size_t used = 0;
    Depth lenient = parse(settings.c_str() + cursor,
                          DDSRT_XMLP_ANONYMOUS_CLOSE_TAG | DDSRT_XMLP_MISSING_CLOSE_AS_EOF, &used);
    if (lenient.failed)
      return "";  // Cyclone stops there with a parse error: nothing after it is read
    if (cursor + used < settings.size() && used > 0) {
      cursor += used;
      continue;
    }
    // the fragment ran to the end of the text: closed, or closed by the end of the text?
    Depth strict = parse(settings.c_str() + cursor, DDSRT_XMLP_ANONYMOUS_CLOSE_TAG);
    std::string closes;
    for (std::size_t i = 0; strict.failed && i < strict.open; ++i) closes += "</>";
    return closes;
  }
  return "";
}

// Cyclone's message for a misspelt element or attribute, with the setting meant:
// "...: AllowMulticst: unknown element (did you mean 'AllowMulticast'?) (...)".
std::string with_suggestion(std::string said) {
  for (const char* what : {": unknown element", ": unknown attribute"}) {
    std::size_t at = said.find(what);
    if (at == std::string::npos) continue;
    std::size_t start = said.rfind(": ", at == 0 ? 0 : at - 1);
    start = start == std::string::npos ? 0 : start + 2;
    std::string suggestion = did_you_mean(said.substr(start, at - start), k_cyclone_setting_names);
    said.insert(at + std::strlen(what), suggestion);
    break;
  }
  return said;
}

}  // namespace

void check_cyclone_config(uint32_t domain, const std::string& config) {
  // the compiled-in loopback settings are known good, Cyclone's defaults too
  const char* resolved = resolve_config(config);
  if (resolved == k_loopback_xml || !*resolved) return;
  const std::string settings = resolved;
  const std::string probe = settings + missing_closing_tags(settings) + "," + k_stop_before_sockets;
  DomainTrial trial = trial_domain(domain, probe.c_str());
  if (trial.result == DDS_RETCODE_PRECONDITION_NOT_MET)
    return;  // the process has the domain: its settings prevail
  std::string complaints;
  for (const auto& line : trial.errors) {
    // our own interface's failure means every setting before it passed
    if (line.find(k_absent_interface) != std::string::npos) continue;
    // Cyclone refuses the deprecated interface settings beside an Interfaces list, ours
    // included: those settings were read without error
    if (line.find("do not pass deprecated configuration") != std::string::npos) continue;
    // "config: //CycloneDDS/Domain: Bogus: unknown element (CYCLONEDDS_URI+0 line 1)"
    std::string said = line.rfind("config: ", 0) == 0 ? line.substr(8) : line;
    complaints += (complaints.empty() ? "" : "; ") + with_suggestion(said);
  }
  if (!complaints.empty())
    throw ConfigError(
        "config: expected Cyclone DDS settings (XML, file names or file:// URIs) that Cyclone "
        "accepts for domain " +
        std::to_string(domain) + ", found settings it refuses: " + complaints);
}

}  // namespace simgate::dds
