"""Adversarial stop-sign textures: a differentiable view of the sign face, and the attacks.

`warp` draws a texture onto the planar sign face in a camera image with a homography
(differentiable in the texture, so an attack can optimise it); `sign_view` reads the
camera and sign geometry it needs from a live MuJoCo scene.
"""
