"""Adversarial stop-sign textures, a library shaped like torchattacks: it makes textures and
measures nothing in the closed loop (that is `avsim.experiments.attacks`), so it imports nothing
from the experiments, the gym or the CLI.

- the methods, one file each, named after their paper (`chen`, `eykholt`, `lu_v2`, `lu_v3`,
  `yang`, plus `driveby` and `range_inflation`), registered in `registry`;
- the differentiable view of the sign: `warp` draws a texture onto the planar sign face in a
  camera image with a homography (differentiable in the texture, so an attack can optimise it),
  `sign_view` reads the camera and sign geometry it needs from a live MuJoCo scene, `view_bank`
  renders the views once, `eot` and `photometric` draw the transformations;
- `targets` (the detectors attacked), `objective`, `bpda` (through a purifier), `budget`
  (SSIM, L-inf, printability) and `generate`, which runs a method and saves its texture.
"""
