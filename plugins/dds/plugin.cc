// The plugin entry point: libsimgate_transport_dds.so exports simgate_transport_dds_entry.
#include "dds_request_manager.h"
#include "simgate/core/plugin.h"

SIMGATE_TRANSPORT_PLUGIN(dds, simgate::dds::DdsRequestManager, "0.1.0", "domain", "partition", "config",
                         "max_samples", "max_in_flight", "park_timeout_ms", "max_params", "max_depth",
                         "global_policy", "progress_interval_ms",
                         "on_disconnect", "stream_writes")
