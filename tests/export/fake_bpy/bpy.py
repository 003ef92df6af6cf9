# A stand-in for Blender's `bpy` module, just enough to execute blender_camera.py outside Blender
# in the export tests. It records what the script does and, at exit, writes it as plain lines
# "what values..." to the file named by EPITRACK_FAKE_BPY_OUT.
import atexit
import os

_log = []


class _Render:
    def __init__(self):
        self.resolution_x = 0
        self.resolution_y = 0
        self.resolution_percentage = 0
        self.pixel_aspect_x = 1.0
        self.pixel_aspect_y = 1.0
        self.fps = 24
        self.fps_base = 1.0


class _Objects:
    def __init__(self):
        self.linked = []

    def link(self, obj):
        self.linked.append(obj)


class _Collection:
    def __init__(self):
        self.objects = _Objects()


class _Scene:
    def __init__(self):
        self.render = _Render()
        self.collection = _Collection()
        self.camera = None
        self.frame_start = 1
        self.frame_end = 250
        self.current = None

    def frame_set(self, frame):
        self.current = frame


class _CameraData:
    def __init__(self, name):
        self.name = name
        self.sensor_fit = 'AUTO'
        self.sensor_width = 36.0
        self.sensor_height = 24.0
        self.lens = 50.0
        self.shift_x = 0.0
        self.shift_y = 0.0
        self.clip_start = 0.1
        self.clip_end = 100.0


class _Mesh:
    def __init__(self, name):
        self.name = name
        self.vertices = []

    def from_pydata(self, vertices, edges, faces):
        self.vertices = [tuple(float(c) for c in v) for v in vertices]

    def update(self):
        pass


class _Object:
    def __init__(self, name, data):
        self.name = name
        self.data = data
        self.location = (0.0, 0.0, 0.0)
        self.rotation_mode = 'XYZ'
        self.rotation_quaternion = (1.0, 0.0, 0.0, 0.0)
        self._properties = {}

    def __setitem__(self, key, value):  # custom properties
        self._properties[key] = value

    def __getitem__(self, key):
        return self._properties[key]

    def keyframe_insert(self, data_path, frame):
        if data_path.startswith('["'):
            value = self._properties[data_path[2:-2]]
        else:
            value = getattr(self, data_path)
        _log.append((data_path, frame, tuple(float(v) for v in value)))


class _Factory:
    def __init__(self, make):
        self._make = make

    def new(self, name, *args):
        return self._make(name, *args)


class _Data:
    cameras = _Factory(_CameraData)
    meshes = _Factory(_Mesh)
    objects = _Factory(_Object)


class _Context:
    scene = _Scene()


context = _Context()
data = _Data()


def _dump():
    path = os.environ.get("EPITRACK_FAKE_BPY_OUT")
    if not path:
        return
    scene = context.scene
    with open(path, "w") as out:
        r = scene.render
        out.write("render %d %d %d %r %r\n" % (r.resolution_x, r.resolution_y,
                                              r.resolution_percentage, r.pixel_aspect_x,
                                              r.pixel_aspect_y))
        out.write("frames %d %d\n" % (scene.frame_start, scene.frame_end))
        out.write("fps %d %r\n" % (r.fps, r.fps_base))
        cam = scene.camera
        if cam is not None:
            d = cam.data
            out.write("camera %s %s %r %r %r %r %r\n" % (cam.rotation_mode, d.sensor_fit,
                                                       d.sensor_width, d.lens, d.shift_x,
                                                       d.shift_y, d.clip_end))
        for what, frame, value in _log:
            out.write("%s %d %s\n" % (what, frame, " ".join(repr(v) for v in value)))
        for obj in scene.collection.objects.linked:
            if isinstance(obj.data, _Mesh):
                for v in obj.data.vertices:
                    out.write("vertex %r %r %r\n" % v)


atexit.register(_dump)
