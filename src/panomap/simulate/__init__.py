"""Simulated omni-cameras and a textured room, as ground truth for tests and demos."""
