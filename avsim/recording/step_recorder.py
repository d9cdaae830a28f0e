"""What every recorder of a run shares (`RunRecorder`, `VideoRecorder`, `BagRecorder`).

A recorder captures the state the loop is in after each step, which is the next step's sensing
state, and writes it with that next step's record (each recorder's docstring says why). This base
class checks that pairing, and gives the recorders their `with` behaviour: `close()` when the block
ends normally, `abort()` (delete the partial file) when it raises.
"""

from __future__ import annotations

from types import TracebackType
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from avsim.loop import ClosedLoop
    from avsim.metrics import StepRecord

# Sensing times of a frame and its record agree to well under one physics step [s].
TIME_TOLERANCE_S = 1e-6


class _Timed(Protocol):
    time_s: float


class StepRecorder:
    """Base of the recorders. A subclass's `__init__` calls `_check_unstarted` first and `_attach`
    once its own arguments are checked, then captures the first state into `_pending`; it defines
    `_capture` (the state now, as a frame with `time_s`), `_step` (what one step writes), `_finish`
    and `_discard`. The base's `on_step`, `close` and `abort` do the rest."""

    _loop: ClosedLoop
    _closed: bool
    _pending: Any

    def _check_unstarted(self, loop: ClosedLoop) -> None:
        """Refuse a loop that has stepped already: its first sensing state is gone."""
        if loop.records:
            raise ValueError(f"attach the {type(self).__name__} before the loop's first step")

    def _attach(self, loop: ClosedLoop) -> None:
        """Record `loop` from now on, its camera renders shared with the perception (`_share_frames`)."""
        self._loop = loop
        self._share_frames(loop)
        self._closed = False

    @staticmethod
    def _share_frames(loop: ClosedLoop) -> None:
        """Let the recorder's render of each sensing state and the perception's share one draw
        (`CameraRig.render_rgb`): in a closed-loop run nothing changes the model's appearance."""
        loop.rig.reuse_last_frame = True

    @staticmethod
    def recorded_cameras(loop: ClosedLoop) -> tuple[str, ...]:
        """The cameras a recording shows: "front" always, then those the policy reads ("side")."""
        return ("front", *(c for c in loop.policy.cameras if c != "front"))

    def on_step(self, loop: ClosedLoop, record: StepRecord) -> None:
        """`loop.run(on_step=...)` hook: write `record` with the frame captured at its sensing time
        (`_step`), then capture the state now, which is the next step's sensing state."""
        frame = self._frame_for(loop, record)
        self._step(frame, record)
        self._pending = self._capture()

    def _capture(self) -> _Timed:
        raise NotImplementedError

    def _step(self, frame: Any, record: StepRecord) -> None:
        raise NotImplementedError

    def _frame_for(self, loop: ClosedLoop, record: StepRecord) -> _Timed:
        """The pending frame, checked to be of `record`'s sensing time in the recorder's own loop."""
        name = type(self).__name__
        if self._closed:
            raise RuntimeError(f"on_step called on a closed {name}")
        if loop is not self._loop:
            raise ValueError(f"on_step called with a different ClosedLoop than the {name} was built for")
        frame = self._pending
        if abs(frame.time_s - record.time_s) > TIME_TOLERANCE_S:
            raise RuntimeError(f"frame at t = {frame.time_s:.3f} s but record at t = {record.time_s:.3f} s: "
                               "on_step must be called once after every loop step")
        return frame

    def close(self) -> None:
        """Finish the recording and move it to its path (the subclass's `_finish`). Idempotent. On any
        error the partial file is discarded (`abort`) and the error raised: nothing half-written stays."""
        if self._closed:
            return
        try:
            self._finish()
        except BaseException:
            self.abort()
            raise
        self._closed = True

    def abort(self) -> None:
        """Stop recording and delete the partial file (the subclass's `_discard`); the path is left untouched."""
        self._closed = True
        self._discard()

    def _finish(self) -> None:
        raise NotImplementedError

    def _discard(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Any:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
