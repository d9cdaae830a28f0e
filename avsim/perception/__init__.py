"""Perception: turns what a camera sees into typed detections (see `base.Perception`)."""
