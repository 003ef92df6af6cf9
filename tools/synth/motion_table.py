#!/usr/bin/env python3
"""Prints the figures of tools/synth/motion_baseline.sh for one or more clip directories.

usage: motion_table.py OUT/NAME [OUT/NAME...]
"""
import json
import re
import sys
from collections import Counter


def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return {}


def gate_losses(log):
    gates = []
    with open(log) as f:
        for line in f:
            m = re.search(r"gate (\d+)", line)
            if line.startswith("frame") and m:
                gates.append(int(m.group(1)))
    return gates


def track_lengths(csv):
    count = Counter()
    with open(csv) as f:
        next(f)
        for line in f:
            count[line.split(',', 2)[1]] += 1
    v = sorted(count.values())
    return sum(v) / len(v), v[len(v) // 2], sum(1 for x in v if x >= 50)


def device(path):
    first, summary = None, {}
    with open(path) as f:
        for line in f:
            if not line.startswith('{'):
                continue
            d = json.loads(line)
            if d.get('summary'):
                summary = d
            elif d.get('status') == 'tracking' and first is None:
                first = d['frame']
    return first, summary


def main():
    if len(sys.argv) < 2:
        sys.stderr.write(__doc__)
        return 2
    for clip in sys.argv[1:]:
        print('==', clip)
        for v in ['default', 'nokalman', 'wholewindow']:
            g = gate_losses(f'{clip}/track_{v}.log')
            mean, median, long = track_lengths(f'{clip}/tracks_{v}.csv')
            a = load(f'{clip}/acc_{v}.json')
            print(f'  track {v}: gate losses {sum(g)} (max {max(g)} in a frame, '
                  f'{sum(1 for x in g if x >= 100)} frames >= 100); track length mean {mean:.1f} '
                  f'median {median}, {long} tracks >= 50 frames; error median {a.get("median")} '
                  f'p95 {a.get("p95")} p99 {a.get("p99")} px, > 3 px {a.get("beyond_3px_pct")} % '
                  f'of observations, {a.get("tracks_beyond_3px_pct")} % of tracks')
        for t in ['own', 'nokalman']:
            for f in ['given', 'self']:
                s = load(f'{clip}/solve_{t}_{f}/summary.json')
                e = load(f'{clip}/eval_{t}_{f}.json')
                ate = e.get('ate_rmse_rel')
                ate = f'{100 * ate:.4f} %' if ate is not None else '-'
                print(f'  solve {t} tracks, focal {f}: {s.get("status")} '
                      f'{s.get("solved_frames")}/{s.get("frames")} frames, ATE {ate}, rotation '
                      f'{e.get("rot_err_deg_mean")} deg, focal error {e.get("focal_err_pct")} %, '
                      f'reprojection {s.get("mean_reproj_px")} px')
        for f in ['given', 'self']:
            first, s = device(f'{clip}/device_{f}.jsonl')
            print(f'  device focal {f}: first tracking frame {first}, tracking {s.get("tracked")}'
                  f'/{s.get("frames")}, median {s.get("ms_median")} ms')
    return 0


if __name__ == '__main__':
    sys.exit(main())
