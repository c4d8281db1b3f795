"""A link's envelope over the joint at the end of its chain: its convex pieces turned through
the joint's whole range, so that the box search need not split that joint at all.

A continuous joint (a wheel, a caster, a forearm or wrist roll) spans a full turn. The box
search bounds how far a box moves a link to first order (``kinematics.box_weights``) or by the
hull of its copies at the box's two corners (``search.LinkPair.corner_bounds``), and both need
the joint cut into many boxes before the bound is small: for a full turn the two corners are
the same pose. A link that turns about its own axis, though, sweeps little more than itself.
Its envelope is the hull of each piece's copies at evenly spaced angles: a point at distance
``rho`` from the axis, turned by an angle between two copies, lies within ``rho * (1 -
cos(step / 2))`` (the chord's sagitta) of the segment joining its two copies, which lies in
the hull. Padded by that much, the envelope holds the piece at every angle of the range, and
a pair whose envelopes never come within the tolerance over the other joints never does.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..geometry import pack_convex
from ..load.robot import rotation
from .distances import LinkGeometry, coarse_pieces, hull_distances

#: The sagitta between two copies, per unit of a point's distance from the axis: copies every
#: ``2 acos(1 - SAGITTA)`` radians (71 over a full turn). Finer copies shrink the pad of a
#: large link turned far (a head over its pan), at set-up work counted per point turned.
SAGITTA = 1.0 / 1000.0
#: ``reach_beyond`` measures from every this-many-th copy.
REACH_STRIDE = 4


def steps(span: float) -> int:
    """How many steps between copies turn a link through ``span`` radians (``SAGITTA``; a
    span past a full turn is a full turn)."""
    return max(1, math.ceil(min(span, 2.0 * math.pi) / (2.0 * math.acos(1.0 - SAGITTA))))


def pieces_of(pack) -> list[np.ndarray]:
    """Each shape's hull vertices in a ``ConvexPack``."""
    return [pack.points[pack.starts[s] : pack.starts[s + 1]] for s in range(len(pack.starts) - 1)]


def turned(points: np.ndarray, origin: np.ndarray, direction: np.ndarray, angles) -> np.ndarray:
    """(K, n, 3) copies of ``points`` turned by each of ``angles`` about the line through
    ``origin`` along the unit ``direction``."""
    moved = points - origin
    return np.stack([moved @ rotation(direction, a).T + origin for a in angles])


def envelope(
    link: LinkGeometry, origin: np.ndarray, direction: np.ndarray, lower: float, upper: float
) -> tuple[LinkGeometry, float]:
    """``link`` turned through ``lower..upper`` radians about the line through ``origin`` along
    the unit ``direction`` (link frame), and how far the envelope reaches beyond the link.

    Each coarse piece is replaced by the hull of its copies at ``K + 1`` evenly spaced angles
    (``SAGITTA``), coarsened again (``distances.coarse_pieces``), with a pad of its own pad,
    the sagitta and the coarsening's. ``points`` are the envelope's vertices and ``points_pad``
    the largest pad: every point of the link at every angle lies within it of their hull.

    Returns
    -------
    LinkGeometry
        The envelope, in the link's frame at the middle of the range; ``parts``, ``vertices``
        and ``faces`` stay the link's own (its real meshes at that angle).
    excess : float
        About how far the envelope (with its pads) reaches beyond the volume the link's pieces
        sweep: each envelope piece's farthest vertex from the nearest copy, plus its pad.
    """
    span = min(upper - lower, 2.0 * math.pi)  # past a full turn, every angle
    count = steps(span)
    angles = np.linspace(-0.5 * span, 0.5 * span, count + 1)
    fall = 1.0 - math.cos(0.5 * span / count)
    pieces = pieces_of(link.pack)
    swept, pads, copies = [], [], []
    for piece, pad in zip(pieces, link.pad, strict=True):
        away = piece - origin
        rho = float(np.linalg.norm(away - np.outer(away @ direction, direction), axis=1).max())
        copies.append(turned(piece, origin, direction, angles))
        swept.append(pack_convex([copies[-1].reshape(-1, 3)]).points)
        pads.append(float(pad) + rho * fall * (1.0 + 1e-9) + 1e-12)
    coarse, coarse_pad = coarse_pieces(swept)
    pad = np.asarray(pads) + coarse_pad
    excess = reach_beyond(coarse, copies) + float(pad.max())
    points = np.vstack(coarse)
    points_pad = float(pad.max())
    (hull,), (hull_pad,) = coarse_pieces([points], min_vertices=0)
    out = dataclasses.replace(
        link,
        pack=pack_convex(coarse, is_hull=True),
        radius=float(np.linalg.norm(points, axis=1).max()) + points_pad,
        pad=pad,
        points=points,
        hull=hull,
        hull_pad=float(hull_pad) + points_pad,
        points_pad=points_pad,
    )
    return out, excess


def reach_beyond(coarse: list[np.ndarray], copies: list[np.ndarray]) -> float:
    """About how far each envelope piece ``coarse[s]`` reaches beyond the volume its piece
    sweeps: the largest distance from the nearest of every ``REACH_STRIDE``-th copy of
    ``copies[s]`` ((K, n, 3), each a convex piece) of the centroids of the envelope's hull
    triangles and of the hull itself (a hull's vertices are the copies' own points; what it
    adds lies across its faces and inside). Only which joints go into an envelope rests on it,
    never a bound."""
    worst = 0.0
    for envelope_piece, turned_copies in zip(coarse, copies, strict=True):
        try:
            hull = ConvexHull(envelope_piece)
            samples = envelope_piece[hull.simplices].mean(axis=1)
        except (QhullError, ValueError):  # flat or degenerate: its vertices stand for it
            samples = envelope_piece
        samples = np.vstack([samples, envelope_piece.mean(axis=0)])
        shown = turned_copies[::REACH_STRIDE]
        pack = pack_convex(list(shown), is_hull=True)
        worst = max(worst, float(hull_distances(pack, samples).min(axis=1).max()))
    return max(worst, 0.0)
