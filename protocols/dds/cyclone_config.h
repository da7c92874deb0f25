// simgate/dds — checking a DDS transport's Cyclone settings (its "config" option) before
// the transport starts, as `simgate check` needs: Cyclone reads them only when it creates
// the domain, and offers no call that only reads them.
//
// check_cyclone_config() lets Cyclone itself judge the settings, short of the network: it
// creates the domain from the settings followed by one more fragment that lists, after the
// settings' own interfaces, an interface no machine has (and sends tracing to stderr), then
// deletes it (trial_domain). Cyclone reads every fragment and file, checks every element,
// attribute and value, the port mapping and the settings' own interfaces, and then fails on
// the absent interface, before it opens any socket: no traffic, no file written, about a
// millisecond. Whatever Cyclone refused before that is the error: unknown elements, bad
// values, XML it cannot parse, a file it cannot open, an interface that does not exist.
// What needs sockets (ports in use, multicast) is left to `run`. The default settings
// ("", the compiled-in loopback XML) and Cyclone's defaults ("env" without CYCLONEDDS_URI)
// are not checked; nor are settings of a domain this process already has (they would be
// ignored: the domain's first settings prevail).
#ifndef SIMGATE_PLUGINS_DDS_CYCLONE_CONFIG_H_
#define SIMGATE_PLUGINS_DDS_CYCLONE_CONFIG_H_

#include <cstdint>
#include <string>

namespace simgate::dds {

// Throws ConfigError("config: expected ..., found ...") with Cyclone's own messages when it
// refuses the settings `config` (the option's value: "", "env", XML text, file names or
// file:// URIs, comma-separated) for domain `domain` (see above). Any thread.
void check_cyclone_config(uint32_t domain, const std::string& config);

}  // namespace simgate::dds

#endif  // SIMGATE_PLUGINS_DDS_CYCLONE_CONFIG_H_
