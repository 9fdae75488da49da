"""The solver on a seed-style example: a static box S and a box M that flies at it
while turning, under a quadratic motion. Prints the route division (octant
switches), the BMS planes at the contact, and the contact itself, then checks
the contact against the boxes' vertices.
"""

from __future__ import annotations

import argparse

import numpy as np

from bullet_boxccd import Box, QuadraticMotion, bms_planes, sections, time_of_impact
from bullet_boxccd.motion import rotation_matrix


def main(argv=None):
    argparse.ArgumentParser(description=__doc__).parse_args(argv)
    S = Box(lo=(-1.0, -0.5, -0.25), hi=(1.0, 0.5, 0.25))  # the seed's (X, Y, Z) and (X', Y', Z')
    M = Box(lo=(0.0, 0.0, 0.0), hi=(0.4, 0.3, 0.2))  # an off-centre box in its own frame
    start = np.eye(4)
    start[:3, :3] = rotation_matrix((1, 2, 3), 0.7)
    start[:3, 3] = (3.0, 1.0, 0.8)
    m_S = QuadraticMotion.static()
    m_M = QuadraticMotion.screw(start, velocity=(-4.0, -1.2, -0.9), angular_velocity=(0.0, 1.5, 2.5))
    print("S:", S, "static")
    print("M:", M, "turning at (0, 1.5, 2.5) rad per unit t while flying at (-4, -1.2, -0.9)")

    cuts = sections(S, m_S, M, m_M)
    print(f"\nroute division: {len(cuts) - 1} sections, boundaries (octant switches) at t =",
          np.array2string(cuts, precision=6))

    c = time_of_impact(S, m_S, M, m_M)
    assert c is not None, "expected a contact"
    print(f"\nfirst contact: t = {c.t:.15f}")
    print(f"  {c.feature.kind} plane: {c.feature.a or '-'} of S against {c.feature.b or '-'} of M")
    print("  point  =", np.array2string(c.point, precision=9))
    print("  normal =", np.array2string(c.normal, precision=9), "(from S towards M)")

    print("\nBMS planes at the contact (the origin lies on the touching one):")
    for plane in bms_planes(S, m_S, M, m_M, c.t):
        mark = " <- touching" if plane.feature == c.feature and abs(plane.offset) < 1e-9 else ""
        print(f"  {plane.feature.kind}  {plane.feature.a:>6} | {plane.feature.b:<6} offset {plane.offset:+.3e}{mark}")

    # Check: at t the boxes touch (the point is on both), and just before they are apart.
    for box, m in ((S, m_S), (M, m_M)):
        X = m.at(c.t)
        local = np.linalg.solve(X[:3, :3], c.point - X[:3, 3])
        assert np.all(local >= box.lo - 1e-9) and np.all(local <= box.hi + 1e-9), "contact point off a box"
    assert time_of_impact(S, m_S, M, m_M, (0.0, c.t - 1e-6)) is None, "a contact before the reported one"
    print("\nchecked: the point lies on both boxes, and they are apart until t.")


if __name__ == "__main__":
    main()
