"""Benchmarks: commands that print speed figures measured on this machine, and assert nothing.

- `speed` (`avsim bench`, `python -m avsim.bench`): physics, rendering, detector latency,
  closed-loop and Gymnasium speed; `gym_env` its rows for `avsim/StopSign-v0`;
- `profile` (`avsim bench --profile`): where one run's and one batch's time goes, by stage;
- `recording_overhead` (`avsim bench --recording`): what `--rrd` and `--mcap` add to a run;
- `sweep_throughput` (`python -m avsim.bench.sweep_throughput`): runs per minute with 1 and 2
  workers and with Ray;
- `detector_latency` (`python -m avsim.bench.detector_latency`): the detector's per-frame
  latency, letterbox / forward / decode + NMS.

Speed targets live here, never in timed unit tests.
"""
