"""Live signals and logs for the tools robotics people already use: each log row as one
JSON object whose per-joint fields group under the joint's name (:mod:`guardid.live.rows`),
streamed over UDP to PlotJuggler during a capture (:mod:`guardid.live.udp`) or written to
an MCAP file for Foxglove and PlotJuggler (:mod:`guardid.live.mcap_log`)."""
