"""Pieces shared by every polyenvs family: planar geometry, argument validation, rendering, rollouts."""
