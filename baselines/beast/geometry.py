"""Rigid-body helpers the beasts' planners share: rotation vectors (Rodrigues) and the Kabsch fit (numpy only)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["kabsch", "rotation_exp", "rotation_log", "unit"]


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def rotation_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of rotation vector ``w`` (Rodrigues)."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-12:
        return np.eye(3) + _skew(w)
    k = _skew(w / angle)
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def rotation_log(r: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (angles below pi, which every planned body motion is)."""
    cos = np.clip((np.trace(r) - 1) / 2, -1.0, 1.0)
    angle = math.acos(cos)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-9:
        return v / 2
    return v * angle / (2 * math.sin(angle))


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def kabsch(p_body: np.ndarray, p_ground: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rot, centre) with rot @ p_body + centre ~ p_ground, least squares (rot body -> ground)."""
    mb, mg = p_body.mean(axis=0), p_ground.mean(axis=0)
    u, _, vt = np.linalg.svd((p_body - mb).T @ (p_ground - mg))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rot, mg - rot @ mb
