#!/usr/bin/env python3
"""COLMAP text models <-> epitrack files, for tools/figures/colmap_reference.sh (standard library only).

  colmap_model.py gt-model DB GROUNDTRUTH "MODEL W H PARAMS..." OUTDIR
      a COLMAP text model whose images (named as in DB) sit at the ground-truth poses, no points
  colmap_model.py to-tum IMAGES_TXT OUT      the model's cameras as cameras.tum (frame = image name)
  colmap_model.py to-tracks IMAGES_TXT OUT   the model's tracks (one per 3D point) as tracks.csv

Conventions: groundtruth / cameras.tum lines are `frame tx ty tz qx qy qz qw`, camera-to-world
(camera centre, Hamilton quaternion); COLMAP's images.txt holds world-to-camera `qw qx qy qz tx ty
tz` and pixel coordinates whose origin is the top-left corner of the first pixel, epitrack's the
centre of that pixel (x_epitrack = x_colmap - 0.5).
"""
import sqlite3
import sys


def qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


def rotate(q, v):
    w, x, y, z = qmul(qmul(q, (0.0, v[0], v[1], v[2])), (q[0], -q[1], -q[2], -q[3]))
    return (x, y, z)


def read_poses(path):
    poses = {}
    for line in open(path):
        f = line.split()
        if not f or f[0].startswith('#'):
            continue
        tx, ty, tz, qx, qy, qz, qw = map(float, f[1:8])
        poses[int(float(f[0]))] = ((tx, ty, tz), (qw, qx, qy, qz))
    return poses


def image_records(images_txt):
    lines = [l for l in open(images_txt) if not l.startswith('#')]
    for k in range(0, len(lines) - 1, 2):
        head = lines[k].split()
        if len(head) < 10:
            continue
        yield head, lines[k + 1].split()


def frame_of(name):
    return int(name.rsplit('/', 1)[-1].split('.')[0])


def gt_model(db, gt, camera, out):
    poses = read_poses(gt)
    images = sqlite3.connect(db).execute('SELECT image_id, name, camera_id FROM images').fetchall()
    with open(out + '/cameras.txt', 'w') as f:
        f.write('1 ' + camera + '\n')
    open(out + '/points3D.txt', 'w').close()
    with open(out + '/images.txt', 'w') as f:
        for image_id, name, camera_id in sorted(images):
            c, q_wc = poses[frame_of(name)]
            q_cw = (q_wc[0], -q_wc[1], -q_wc[2], -q_wc[3])
            t = rotate(q_cw, c)
            f.write('%d %.12f %.12f %.12f %.12f %.12f %.12f %.12f %d %s\n\n' %
                    (image_id, *q_cw, -t[0], -t[1], -t[2], camera_id, name))


def to_tum(images_txt, out):
    rows = []
    for head, _ in image_records(images_txt):
        q_cw = tuple(map(float, head[1:5]))
        t = tuple(map(float, head[5:8]))
        q_wc = (q_cw[0], -q_cw[1], -q_cw[2], -q_cw[3])
        c = rotate(q_wc, (-t[0], -t[1], -t[2]))
        rows.append((frame_of(head[9]), c, q_wc))
    with open(out, 'w') as f:
        for frame, c, q in sorted(rows):
            f.write('%d %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n' % (frame, *c, q[1], q[2], q[3], q[0]))


def to_tracks(images_txt, out):
    rows = []
    for head, points in image_records(images_txt):
        frame = frame_of(head[9])
        for j in range(0, len(points) - 2, 3):
            point_id = int(points[j + 2])
            if point_id >= 0:
                rows.append((frame, point_id, float(points[j]) - 0.5, float(points[j + 1]) - 0.5))
    with open(out, 'w') as f:
        f.write('frame,track_id,x,y\n')
        for r in sorted(rows):
            f.write('%d,%d,%.3f,%.3f\n' % r)


if __name__ == '__main__':
    cmd = sys.argv[1] if len(sys.argv) > 1 else ''
    if cmd == 'gt-model' and len(sys.argv) == 6:
        gt_model(*sys.argv[2:6])
    elif cmd == 'to-tum' and len(sys.argv) == 4:
        to_tum(*sys.argv[2:4])
    elif cmd == 'to-tracks' and len(sys.argv) == 4:
        to_tracks(*sys.argv[2:4])
    else:
        sys.exit(__doc__)
