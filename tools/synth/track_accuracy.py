#!/usr/bin/env python3
"""Scores a tracks.csv (epitrack-track) against an epitrack-synth clip's landmarks.txt.

The measure of tests/tracker/orbit_clip.cpp (measureTracker): a track is associated with the
nearest landmark within 1 px of its first observation; each later observation is compared with
that landmark's true projection in the same frame, and counts as infinitely far when the
landmark is not visible there (occluded or out of view). Prints one JSON object: observations,
median, p95, p99 (px), beyond_3px_pct (observations), tracks_beyond_3px_pct (associated tracks
off by more than 3 px at some point), mean and median track length (frames).

usage: track_accuracy.py CLIP_DIR/landmarks.txt tracks.csv
"""
import json
import math
import sys
from collections import defaultdict


def percentile(values, q):
    # The index rule of orbit_clip.cpp percentile(): floor(q * (n - 1)) of the sorted values.
    if not values:
        return 0.0
    s = sorted(values)
    return s[int(q * (len(s) - 1))]


def main():
    if len(sys.argv) != 3:
        sys.stderr.write(__doc__)
        return 2
    truth = defaultdict(dict)
    with open(sys.argv[1]) as f:
        for line in f:
            if line.startswith('#') or not line.strip():
                continue
            fr, lid, x, y = line.split()
            truth[int(fr)][int(lid)] = (float(x), float(y))
    tracks = defaultdict(list)
    with open(sys.argv[2]) as f:
        next(f)  # header
        for line in f:
            fr, tid, x, y = line.strip().split(',')
            tracks[int(tid)].append((int(fr), float(x), float(y)))
    errors = []
    bad_tracks = 0
    associated = 0
    lengths = []
    for obs in tracks.values():
        obs.sort()
        lengths.append(len(obs))
        f0, x0, y0 = obs[0]
        best, landmark = 1.0, None
        for lid, (lx, ly) in truth[f0].items():
            d2 = (lx - x0) ** 2 + (ly - y0) ** 2
            if d2 <= best:
                best, landmark = d2, lid
        if landmark is None:
            continue
        associated += 1
        worst = 0.0
        for fr, x, y in obs[1:]:
            p = truth[fr].get(landmark)
            e = math.inf if p is None else math.hypot(x - p[0], y - p[1])
            errors.append(e)
            worst = max(worst, e)
        bad_tracks += worst > 3.0
    n = len(errors)
    out = {
        'observations': n,
        'associated_tracks': associated,
        'median': percentile(errors, 0.5),
        'p95': percentile(errors, 0.95),
        'p99': percentile(errors, 0.99),
        'beyond_3px_pct': 100.0 * sum(e > 3.0 for e in errors) / n if n else 0.0,
        'tracks_beyond_3px_pct': 100.0 * bad_tracks / associated if associated else 0.0,
        'track_length_mean': sum(lengths) / len(lengths) if lengths else 0.0,
        'track_length_median': percentile(lengths, 0.5),
    }
    print(json.dumps({k: (round(v, 4) if isinstance(v, float) and math.isfinite(v) else
                          (str(v) if isinstance(v, float) else v)) for k, v in out.items()}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
