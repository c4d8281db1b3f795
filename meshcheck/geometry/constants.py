"""Numeric tolerances of the geometry kernels, in one place, each with the reason for its value.

Every tolerance here is *relative*: it is multiplied by a length taken from the shapes of the
query, so the kernels behave the same for a 1e-3 mm pin and a 1e4 mm frame, and for parts placed
1e5 units from the origin.

Two lengths are used:

``size``
    The largest axis-aligned bounding-box edge of the two shapes of a query. It sets the default
    touching tolerance and the thresholds for "zero" and "degenerate" inside the kernels.
``coord``
    The largest absolute coordinate of the two shapes (before re-centring). Input coordinates are
    only known to half an ulp of this, so the default tolerance never drops below a few ulps of it.

The compiled kernels (``src/``) read these values from this module when they are imported, so
this file stays the one place they are set. The status codes they return live here too;
:class:`meshcheck.geometry.Status` mirrors them.
"""

from __future__ import annotations

import numpy as np

EPS = float(np.finfo(np.float64).eps)

# ---------------------------------------------------------------------------------------------
# Default tolerance (used when the caller passes ``tolerance=None``)
# ---------------------------------------------------------------------------------------------

#: Default touching tolerance as a fraction of ``size``. 1e-10 is about 1e6 ulps of the shape's
#: size: far above the rounding of a GJK step in re-centred coordinates (tens of ulps), and far
#: below any gap a mechanical model means (a float32 STL export already carries ~1e-7 of noise,
#: which is why the pipeline passes its own, larger tolerance).
TOUCH_REL = 1e-10

#: Floor of the default tolerance as a fraction of ``coord``: the inputs themselves are rounded
#: to half an ulp of their magnitude (1.1e-16 relative), and re-centring, dot products and the
#: simplex projections add a few more ulps. 64 ulps leaves a margin of ~10x on that.
COORD_REL = 64.0 * EPS

# ---------------------------------------------------------------------------------------------
# GJK
# ---------------------------------------------------------------------------------------------

#: GJK stops when ``upper - lower <= GJK_REL_GAP * upper`` (parry's stopping rule on the gap
#: between the distance bounds). 1e-10 gives distances to ~10 significant digits, which is far
#: more than the inputs deserve, and still stops in a handful of iterations on polytopes
#: (GJK on a polytope usually ends earlier anyway, when a support point repeats).
GJK_REL_GAP = 1e-10

#: Iteration cap for GJK. On polytopes GJK ends in a few to ~20 iterations; 128 only triggers on
#: numerical trouble, and then the answer is decided from the bounds or reported UNDECIDED.
GJK_MAX_ITER = 128

#: ``|v| <= ZERO_REL * size`` means the origin lies on the current simplex (the shapes meet up to
#: rounding). A GJK step in re-centred coordinates is accurate to ~10 ulps of ``size`` (~2e-15),
#: so 1e-13 is above the noise and 1000x below :data:`TOUCH_REL`, which keeps "touching" decided
#: by the caller's tolerance and not by this threshold. It is also capped at half the tolerance.
ZERO_REL = 1e-13

#: A simplex is treated as degenerate (a flat tetrahedron, a needle triangle) when its volume or
#: area is below this fraction of the product of its edge lengths (a sine, in effect). Below
#: ~1e-10 the sign of an orientation test is no longer reliable in float64 (it cancels ~10 digits
#: of 16); the degenerate case is handled through the lower-dimensional faces, which is exact.
DEGENERATE_SIN = 1e-10

# ---------------------------------------------------------------------------------------------
# EPA
# ---------------------------------------------------------------------------------------------

#: EPA stops when ``upper - lower <= EPA_REL_GAP * upper`` on the penetration depth, the same
#: rule as GJK's on the distance.
EPA_REL_GAP = 1e-10

#: Iteration cap for EPA (one new polytope vertex per iteration). Depths of random 40-vertex
#: hull pairs converge in ~10-40 iterations; the cap bounds the work arrays. When it triggers the
#: status is still decided from the depth bounds where they allow it, else UNDECIDED.
EPA_MAX_ITER = 128

# ---------------------------------------------------------------------------------------------
# Support maps
# ---------------------------------------------------------------------------------------------

#: Shapes with more hull vertices than this walk the vertex adjacency (hill climbing) to find a
#: support point; smaller ones are scanned. A walk touches few vertices (~40 of 1000, ~100 from
#: a cold start) but in pointer-chasing order, while a scan streams memory the prefetcher
#: loves: on random ellipsoid hulls each used in one pair (cold cache) the scan stayed faster up to
#: ~1000 vertices (bench/gjk.py measures the kernel). Large body hulls queried in several pairs
#: are warm and climb well.
HILL_CLIMB_MIN_VERTICES = 1024

#: ``query_pairs(..., threads=N)`` spreads the pairs over N threads only from this many pairs
#: on: starting and joining the threads costs tens of microseconds, a few hundred 40-vertex pairs.
PARALLEL_MIN_PAIRS = 256

# ---------------------------------------------------------------------------------------------
# Depth of a shared solid (``meshcheck.verify.depth``): the largest ball inside it
# ---------------------------------------------------------------------------------------------

#: Two faces sharing an edge are flat there when their unit normals' dot product is within this
#: of 1 (an angle below 4.5e-5 rad): a wall's diagonal, a cap's fan. Such an edge casts only its
#: faces' own rays, so seeding skips it. Far above the rounding of a unit normal (~1e-16), far
#: below any bend a model means.
FLAT_EDGE_COS = 1e-9

#: A bisector of two unit normals shorter than this (faces folded back onto each other, a knife
#: edge) has no reliable direction (its rounding, ~1e-16 / 1e-6, turns it by 1e-10 rad at most
#: above it), so the edge casts no ray.
MIN_BISECTOR = 1e-6

#: A seed ray ignores hits closer than this fraction of the solid's size to its start: the
#: faces it starts on (a few ulps away after rounding) are not the far wall it looks for.
RAY_SKIP_REL = 1e-9

#: The ball's ascent stops when a step grows the radius by less than this fraction: LP rounding
#: (~1e-15 relative) would otherwise keep it stepping in place.
ASCENT_REL = 1e-10

#: Safety factor on an LP's upper bound on the ball: the bound is computed in float64 from a
#: scaled problem, so it is widened by 1e-12 (a thousand ulps) to stay an upper bound.
BOUND_SAFETY_REL = 1e-12

#: An LP dual weight below this does not count a polygon as bounding the ball (HiGHS reports
#: zero duals to ~1e-12).
DUAL_WEIGHT_MIN = 1e-9

#: Triangles sharing an edge lie on one plane when their unit normals agree within ``1 - COS``
#: (1e-15: a few ulps, i.e. exactly, up to rounding) and their planes' offsets within
#: ``COPLANAR_OFFSET_REL`` of the solid's size (1e-13: re-centred float64 coordinates carry
#: ~1e-16 relative noise, a few hundred times that after a boolean's intersections).
COPLANAR_COS = 1e-15
COPLANAR_OFFSET_REL = 1e-13

#: Coplanar triangles cover a convex polygon when their area equals their hull's within this
#: fraction (summing triangle areas rounds to ~1e-15 relative; a notch any smaller is no notch).
CONVEX_AREA_REL = 1e-12

# ---------------------------------------------------------------------------------------------
# Status codes (mirrored by ``meshcheck.geometry.gjk.Status``)
# ---------------------------------------------------------------------------------------------

SEPARATED = 0
TOUCHING = 1
PENETRATING = 2
UNDECIDED = 3
