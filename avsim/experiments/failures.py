"""Which finished runs count as *failed*: the runs a researcher wants to look at (`--rrd failed`).

A run is failed when the car did not do what the junction asked of it:
- a stop was required (a stop sign faces the car) and the car did not stop with its bumper at
  or before the sign: `ran_past_sign`, `never_braked` or `timed_out_before_sign`. Stopping
  past the line but before the sign (`stopped_past_line`) is a stop, as in the study;
- a stop was required and the car stopped for something short of the junction: it came to rest
  farther before the line than its policy's braking gate reaches
  (`avsim.metrics.rested_beyond_gate`), so braking began on a false stop sign, or on the sign's
  box stretched over what stands behind it. The reports count such a run as a stop, as the study
  would, and name it beside the stop rate; on a road it is a phantom brake, and its recording is
  what shows what the network saw;
- no stop was required and the car stopped for nothing (`phantom_stop`), timed out, or
  braked harder than `avsim.metrics.PHANTOM_BRAKE_LEVEL` on the way (a phantom brake).

A run that raised an error (status "failed" in the batch record) has no result and no
recording: its recorder deletes the partial file, as every avsim output does. Running
`avsim run --config ... --cell ... --seed ...` raises the same error again.
"""

from __future__ import annotations

from avsim.metrics import STOPPED_BEFORE_SIGN, RunResult, is_phantom_brake


def is_failed_run(result: RunResult) -> bool:
    """Whether `result` is a failure of the car (see the module docstring)."""
    if result.stop_required:
        return result.outcome not in STOPPED_BEFORE_SIGN or result.rested_beyond_gate
    return result.outcome != "drove_through" or is_phantom_brake(result.stop_required, result.max_brake)
