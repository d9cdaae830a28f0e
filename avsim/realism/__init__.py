"""`avsim realism`: do avsim's renders look like the world to detectors trained on photographs?

A fixed, seeded set of frames per town, camera and distance (`frame_set`), rendered under each
named render setting (`settings`), scored by every real detector and the own one (`scoring`),
reported as tables and a figure (`report`); `benchmark` runs it, with `--set` values checked by `set_values`.
docs/realism.md has the results.
"""
