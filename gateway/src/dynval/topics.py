"""The MCAP topics dynval writes (mcap_log) and reads back (io.mcapfile, inspect, run): the one
place their names are spelled."""
from __future__ import annotations

T_RAW = "/can/raw"  # every frame, raw
T_FEATURES = "/dv/features"  # DV_FEATURE, decoded
T_RESID = "/dv/residuals"  # DV_RESID, decoded
T_STATUS = "/dv/status"  # DV_STATUS, decoded
T_CONTROL = "/dv/control"  # DV_CTRL and DV_CHCFG, decoded
T_EVENTS = "/dv/events"  # counted anomalies: refused frames, sequence gaps
T_SAMPLES = "/dv/samples/"  # + channel name: DV_SAMPLES, decoded and scaled, one per sample
T_LOG = "/dv/log"  # foxglove.Log: run control and anomalies as text, for a log panel
#: channel metadata of the protobuf topics: the channel names by number (a JSON list), which
#: features and residuals carry as a number only
CHANNEL_NAMES_KEY = "dynval.channel_names"
