#!/usr/bin/env python3
"""Heading increments of an estimate against its reference, pose pair by pose pair.

Usage: python3 scripts/turns.py REFERENCE ESTIMATE.tum

REFERENCE is a `time x y phi` file (a CARMEN import's reference.txt) or a TUM file; ESTIMATE a
TUM file from `uwbloc compare`. The estimate's poses are paired with the reference's at the same
stamps (within 1 ms), and for each pair of consecutive stamps the heading turned by the estimate
is compared with the reference's. Prints the RMS of the per-pair heading error, its sum (the
heading drift it adds up to), and the least-squares ratio of the estimate's turns to the
reference's over the pairs that turned more than 5 degrees: a LiDAR odometry whose rays are
spaced wrongly turns by that spacing's ratio to the true one.

Standard library only: a diagnostic for LiDAR odometry (`lidar-icp`), not part of the build.
"""
import math
import sys


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def read_poses(path):
    """{stamp in ms: (x, y, heading)} from a TUM or `time x y phi` file."""
    poses = {}
    with open(path) as f:
        for number, line in enumerate(f, 1):
            fields = line.split()
            if not fields or fields[0].startswith('#'):
                continue
            try:
                v = [float(x) for x in fields]
            except ValueError:
                sys.exit(f"{path}:{number}: not a number in '{line.strip()}'")
            if len(v) >= 8:
                heading = 2 * math.atan2(v[6], v[7])
            elif len(v) >= 4:
                heading = v[3]
            else:
                sys.exit(f"{path}:{number}: expected 't x y phi' or a TUM row")
            poses[round(v[0] * 1000)] = (v[1], v[2], heading)
    return poses


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    ref = read_poses(sys.argv[1])
    est = read_poses(sys.argv[2])
    stamps = sorted(s for s in ref if s in est)
    if len(stamps) < 2:
        sys.exit(f"fewer than 2 stamps shared by {sys.argv[1]} and {sys.argv[2]}")
    errors = []
    sxx = sxy = 0.0
    for a, b in zip(stamps, stamps[1:]):
        turn_ref = wrap(ref[b][2] - ref[a][2])
        turn_est = wrap(est[b][2] - est[a][2])
        error = wrap(turn_est - turn_ref)
        errors.append(math.degrees(error))
        if abs(turn_ref) > math.radians(5) and abs(error) < math.radians(5):
            sxx += turn_ref * turn_ref
            sxy += turn_ref * turn_est
    rms = math.sqrt(sum(e * e for e in errors) / len(errors))
    print(f"pairs {len(errors)}  heading error per pair: rms {rms:.3f} deg, "
          f"sum {sum(errors):+.2f} deg")
    if sxx > 0:
        print(f"turns over 5 deg: estimate / reference {sxy / sxx:.5f}")


if __name__ == '__main__':
    main()
