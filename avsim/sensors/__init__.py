"""Cameras on the car: intrinsics, poses, offscreen RGB and segmentation rendering."""
