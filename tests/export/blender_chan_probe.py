# Run inside Blender (tests/export/blender_real_test.cpp):
#   blender -b --factory-startup --python-exit-code 1 --python blender_chan_probe.py -- \
#       OUT CHAN WIDTH HEIGHT POINTS
# Imports CHAN onto the default scene's camera with Blender's bundled Nuke .chan importer
# (io_anim_nuke_chan: rotation order ZXY, "Make Z up", the sensor height set for the image's
# aspect), the steps docs/exports.md gives, and writes to OUT the camera's pose at every keyed
# frame and Blender's projection (world_to_camera_view) of the points of POINTS (x y z per line).
import sys

import addon_utils
import bpy
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

out_path, chan_path, width, height, points_path = sys.argv[sys.argv.index("--") + 1:][:5]
width, height = int(width), int(height)
addon_utils.enable("io_anim_nuke_chan", default_set=True)
scene = bpy.context.scene
scene.render.resolution_x = width
scene.render.resolution_y = height
scene.render.resolution_percentage = 100
camera = bpy.data.objects["Camera"]
camera.rotation_mode = 'QUATERNION'
bpy.context.view_layer.objects.active = camera
sensor_width = 36.0
bpy.ops.import_scene.import_chan(filepath=chan_path, rotation_order='ZXY', z_up=True,
                                 sensor_width=sensor_width,
                                 sensor_height=sensor_width * height / width)
points = []
with open(points_path) as f:
    for line in f:
        if line.strip():
            points.append(Vector([float(v) for v in line.split()]))
frames = sorted({int(k.co[0]) for fc in camera.animation_data.action.fcurves
                 for k in fc.keyframe_points})
lines = []
for frame in frames:
    scene.frame_set(frame)
    m = camera.matrix_world
    q = m.to_quaternion()
    lines.append("pose %d %r %r %r %r %r %r %r" % (frame, m.translation.x, m.translation.y,
                                                   m.translation.z, q.w, q.x, q.y, q.z))
    for i, co in enumerate(points):
        p = world_to_camera_view(scene, camera, co)
        lines.append("view %d %d %r %r %r" % (frame, i, p.x, p.y, p.z))
with open(out_path, "w") as out:
    out.write("\n".join(lines) + "\n")
