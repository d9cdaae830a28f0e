"""What `avsim attack generate` uses where neither a flag nor a record names it, in a module that imports nothing
heavy, so that the command line can print it in its help without loading torch."""

from __future__ import annotations

# Methods whose objective is a closed-loop drive-by: they get the closed loop's bank and sensor, with frames
# spaced by the attacked speed.
CLOSED_LOOP_METHODS = ("driveby", "range_inflation")
# Torch threads of an optimisation; recorded, since a texture's last bits depend on the count.
DEFAULT_THREADS = 2
# The attacked speed [km/h]: the study's.
DEFAULT_ATTACKED_SPEED_KMH = 85.0
