# Run inside Blender after blender_camera.py (tests/export/blender_real_test.cpp):
#   blender -b --factory-startup --python-exit-code 1 --python blender_camera.py \
#       --python blender_probe.py -- OUT [PLATE_DIR FRAME...]
# Writes what Blender itself made of the export, as plain lines "what values...", to OUT: the
# scene's timing, the plate clip, the camera pose at every frame and Blender's own projection
# (bpy_extras world_to_camera_view: x, y in [0, 1] from the bottom-left corner of the frame, z the
# depth) of every vertex of the point cloud. With PLATE_DIR, also the gray level of the top-left
# pixel of the plate clip as the compositor renders it at each FRAME (files in PLATE_DIR), which
# says which input frame Blender shows at that frame.
import sys

import bpy
from bpy_extras.object_utils import world_to_camera_view

args = sys.argv[sys.argv.index("--") + 1:]
out_path = args[0]
scene = bpy.context.scene
camera = bpy.data.objects["epitrack_camera"]
points = bpy.data.objects["epitrack_points"]
lines = []
r = scene.render
lines.append("render %d %d %r %r" % (r.resolution_x, r.resolution_y, r.pixel_aspect_x,
                                     r.pixel_aspect_y))
lines.append("fps %d %r" % (r.fps, r.fps_base))
lines.append("frames %d %d" % (scene.frame_start, scene.frame_end))
clip = scene.active_clip
if clip is not None:
    lens = clip.tracking.camera
    principal = lens.principal_point_pixels if hasattr(lens, "principal_point_pixels") \
        else lens.principal
    lines.append("clip %d %d %d %d %r %r %r %r %r %r" % (
        clip.size[0], clip.size[1], clip.frame_start, clip.frame_duration,
        lens.focal_length_pixels, lens.pixel_aspect, principal[0], principal[1], lens.k1,
        lens.k2))
    backgrounds = [b for b in camera.data.background_images if b.clip == clip]
    lines.append("background %d %d" % (len(backgrounds), int(camera.data.show_background_images)))
world = [points.matrix_world @ v.co for v in points.data.vertices]
for i, co in enumerate(world):
    lines.append("vertex %d %r %r %r" % (i, co.x, co.y, co.z))
for frame in range(scene.frame_start, scene.frame_end + 1):
    scene.frame_set(frame)
    m = camera.matrix_world
    q = m.to_quaternion()
    lines.append("pose %d %r %r %r %r %r %r %r" % (frame, m.translation.x, m.translation.y,
                                                   m.translation.z, q.w, q.x, q.y, q.z))
    for i, co in enumerate(world):
        p = world_to_camera_view(scene, camera, co)
        lines.append("view %d %d %r %r %r" % (frame, i, p.x, p.y, p.z))
if len(args) > 2 and clip is not None:
    # The compositor alone: the clip to the Composite output, rendered at each asked frame with
    # the Standard view transform so that gray levels come back as they are in the files.
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 1
    scene.view_settings.view_transform = 'Standard'
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'BW'
    scene.use_nodes = True
    tree = scene.node_tree
    for node in list(tree.nodes):
        tree.nodes.remove(node)
    source = tree.nodes.new('CompositorNodeMovieClip')
    source.clip = clip
    composite = tree.nodes.new('CompositorNodeComposite')
    tree.links.new(source.outputs['Image'], composite.inputs['Image'])
    for frame in (int(a) for a in args[2:]):
        scene.frame_set(frame)
        scene.render.filepath = "%s/plate_%d.png" % (args[1], frame)
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(scene.render.filepath)
        # Pixels are stored bottom row first: the top-left pixel starts the last row.
        top_left = 4 * (image.size[1] - 1) * image.size[0]
        lines.append("plate %d %r" % (frame, image.pixels[top_left] * 255.0))
with open(out_path, "w") as out:
    out.write("\n".join(lines) + "\n")
