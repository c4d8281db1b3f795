"""A kinematic chain's placements at many poses in one compiled loop (the sweep's).

The work is C++ (``src/placed.hpp``, ``chain_placements``); this function checks and converts
its arguments and raises ``ValueError`` on malformed input.
"""

from __future__ import annotations

import numpy as np

from . import _kernels

#: ``kinds`` of ``chain_placements``' joints.
TURN, SLIDE = 0, 1


def chain_placements(
    before, kinds, axes, after, values, scale: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A chain's last link placed at each row of ``values``, and its joints' axis lines.

    Parameters
    ----------
    before : (J, 4, 4) float64
        The fixed transform before each movable joint: its origin, and the fixed joints since
        the previous movable one.
    kinds : (J,) int64
        ``TURN`` (about the joint's axis, radians) or ``SLIDE`` (along it).
    axes : (J, 3) float64
        Each joint's unit axis, in its own frame.
    after : (4, 4) float64
        The fixed transforms after the last movable joint.
    values : (E, J) float64
        The joints' values at each pose.
    scale : float
        Report units per unit of the chain's lengths.

    Returns
    -------
    placed : (E, 4, 4) float64
        ``before[0] M_0(values[e, 0]) ... before[J-1] M_{J-1} after``, its translation times
        ``scale``.
    points, directions : (E, J, 3) float64
        Each joint's axis line at each pose, in the chain's root frame: a point on it (times
        ``scale``) and its unit direction.

    Examples
    --------
    >>> import numpy as np
    >>> up = np.eye(4)
    >>> up[2, 3] = 1.0  # a turn about z, one unit above the root
    >>> placed, points, directions = chain_placements(
    ...     up[None], [TURN], [[0.0, 0.0, 1.0]], np.eye(4), [[np.pi / 2]], 10.0)
    >>> np.round(placed[0], 12)
    array([[ 0., -1.,  0.,  0.],
           [ 1.,  0.,  0.,  0.],
           [ 0.,  0.,  1., 10.],
           [ 0.,  0.,  0.,  1.]])
    >>> points[0, 0], directions[0, 0]
    (array([ 0.,  0., 10.]), array([0., 0., 1.]))
    """
    return _kernels.chain_placements(
        np.ascontiguousarray(before, dtype=np.float64),
        np.ascontiguousarray(kinds, dtype=np.int64),
        np.ascontiguousarray(axes, dtype=np.float64),
        np.ascontiguousarray(after, dtype=np.float64),
        np.ascontiguousarray(values, dtype=np.float64),
        float(scale),
    )
