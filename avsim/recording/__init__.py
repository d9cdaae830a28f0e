"""Recording closed-loop runs for inspection: rerun `.rrd` files (`avsim run --rrd`).

Importing this package does not import rerun; `avsim.recording.rerun_log` does.
"""
