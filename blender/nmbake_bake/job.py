"""One bake from the scene's nmbake settings: export, bake through the live
session, load the maps back. UI-free; the operators and the auto re-bake
drive it (ui.py).

A Job is started on Blender's main thread (start(): the export needs bpy),
waits for nmbake in a thread of its own (the session's answers, progress
included, arrive there), and is finished on the main thread again
(finish(): images and materials).
"""

import atexit
import hashlib
import os
import shutil
import tempfile
import threading
import time

import numpy as np

from . import export

try:  # the copy the add-on zip carries (tools/blender-addon)
    from . import nmbake as client
except ImportError:  # a checkout: python/ on sys.path
    import nmbake as client

# Maps stored as data, not colour: everything but the colour maps.
_COLOUR_MAPS = {"base-color", "emissive", "vertex-color", "id"}

_session = None
_session_binary = None
_session_lock = threading.Lock()

# Object name -> (PLY path, geometry fingerprint) of high meshes written in
# this Blender session; an unchanged high is not written again (its file
# then keeps its bytes, and the server its loaded mesh and BVH).
_high_files = {}
_export_root = None


def remove_exports():
    """Removes this Blender process's exported meshes (at exit, and when the
    add-on is disabled)."""
    global _export_root
    if _export_root is not None:
        shutil.rmtree(_export_root, ignore_errors=True)
        _export_root = None
        _high_files.clear()


def _at_exit():
    close_session()
    remove_exports()


atexit.register(_at_exit)


def export_root():
    """The folder of this Blender process's exported meshes (the same
    paths for every bake, so the session recognises the high)."""
    global _export_root
    if _export_root is None or not os.path.isdir(_export_root):
        _export_root = tempfile.mkdtemp(prefix="nmbake_blender_")
    return _export_root


def find_nmbake(preference_path):
    """The binary: the add-on preference, else $NMBAKE, else PATH."""
    return client.find_binary(preference_path or None)


def session_for(binary):
    """The live session (`nmbake serve`) for `binary`, started on first use
    and again when the binary changed or the server ended."""
    global _session, _session_binary
    with _session_lock:
        alive = _session is not None and _session._process.poll() is None and not _session._closed
        if alive and _session_binary == binary:
            return _session
        if _session is not None:
            _session.close()
        _session = client.Session(nmbake=binary)
        _session_binary = binary
        return _session


def close_session():
    global _session
    with _session_lock:
        if _session is not None:
            _session.close()
            _session = None


def output_folder(path):
    """The output folder as an absolute path ("//" is the .blend's folder)."""
    import bpy

    if path.startswith("//") and not bpy.data.filepath:
        raise BakeError("the output folder is relative to the .blend file: save it first, or choose an absolute folder")
    return os.path.abspath(bpy.path.abspath(path))


def mesh_objects(obj, collection):
    """The mesh objects of a role: the collection's (recursively, sorted by
    name) when one is set, else the object."""
    if collection is not None:
        return sorted((o for o in collection.all_objects if o.type == "MESH"), key=lambda o: o.name)
    if obj is not None and obj.type == "MESH":
        return [obj]
    return []


def role_name(obj, collection):
    if collection is not None:
        return collection.name
    return obj.name if obj is not None else ""


def fingerprint(objects, depsgraph, uv_name=""):
    """A hash of what the export of `objects` mostly depends on: the
    evaluated positions, the loops' vertices, smooth flags, UVs and world
    matrices (not custom normals or auto smooth angles)."""
    digest = hashlib.blake2b(digest_size=16)
    for obj in objects:
        mesh = obj.evaluated_get(depsgraph).data  # read only
        digest.update(obj.name.encode("utf-8"))
        digest.update(np.array(obj.matrix_world, dtype=np.float64).tobytes())
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        digest.update(co.tobytes())
        loops = np.empty(len(mesh.loops), np.uint32)
        mesh.loops.foreach_get("vertex_index", loops)
        digest.update(loops.tobytes())
        smooth = np.empty(len(mesh.polygons), dtype=bool)
        mesh.polygons.foreach_get("use_smooth", smooth)
        digest.update(smooth.tobytes())
        layer = export.uv_layer_of(mesh, uv_name)
        if layer is not None:
            uv = np.empty(len(mesh.loops) * 2, np.float32)
            layer.data.foreach_get("uv", uv)
            digest.update(uv.tobytes())
    return digest.hexdigest()


def blender_tangents(obj, depsgraph, uv_name):
    """Blender's own MikkTSpace tangents (calc_tangents on the evaluated
    mesh, quads and n-gons as Blender gives them to MikkTSpace) per loop, in
    world space: (tangents (N, 3), signs (N,))."""
    obj_eval = obj.evaluated_get(depsgraph)
    mesh = obj_eval.to_mesh()
    try:
        mesh.calc_tangents(uvmap=uv_name)
        count = len(mesh.loops)
        tangents = np.empty(count * 3, np.float32)
        mesh.loops.foreach_get("tangent", tangents)
        signs = np.empty(count, np.float32)
        mesh.loops.foreach_get("bitangent_sign", signs)
    finally:
        obj_eval.to_mesh_clear()
    tangents = tangents.reshape(count, 3)
    m = np.array(obj.matrix_world, dtype=np.float64)
    if not np.array_equal(m, np.eye(4)):
        t = tangents.astype(np.float64) @ m[:3, :3].T
        length = np.linalg.norm(t, axis=1, keepdims=True)
        length[length == 0.0] = 1.0
        tangents = (t / length).astype(np.float32)
        if np.linalg.det(m[:3, :3]) < 0.0:
            signs = -signs
    return tangents, signs


class BakeError(Exception):
    pass


class Job:
    """A bake in flight. Fields the UI reads: stage, fraction, done,
    report, error, timings (seconds: export, bake, load)."""

    def __init__(self, settings, binary):
        self.settings = settings
        self.binary = binary
        self.stage = "export"
        self.fraction = 0.0
        self.done = False
        self.report = None
        self.error = None
        self.cancelled = False
        self.timings = {}
        self.request = None
        self.low_objects = []
        self.uv_names = {}
        self.request_keys = None
        self.low_fingerprint = None
        self.quads = 0
        self._thread = None

    # -- main thread ------------------------------------------------------

    def start(self, context):
        """Exports the meshes and sends the bake. Raises BakeError."""
        s = self.settings
        depsgraph = context.evaluated_depsgraph_get()
        low = mesh_objects(s.low_object, s.low_collection)
        high = mesh_objects(s.high_object, s.high_collection)
        cage = mesh_objects(s.cage_object, s.cage_collection)
        if not low:
            raise BakeError("no low mesh: pick an object or a collection with mesh objects")
        if not high:
            raise BakeError("no high mesh: pick an object or a collection with mesh objects")
        if set(o.name for o in low) & set(o.name for o in high):
            raise BakeError("an object is both low and high")
        maps = sorted(s.maps) if s.maps else ["normal"]
        if not s.output_dir:
            raise BakeError("no output folder")
        out_dir = output_folder(s.output_dir)
        template = s.name_template or "<LOW>_<MAP>.png"
        if len(maps) > 1 and "<MAP>" not in template:
            raise BakeError("several maps need <MAP> in the name template")
        t0 = time.perf_counter()
        root = export_root()
        for sub in ("low", "high", "cage"):
            os.makedirs(os.path.join(root, sub), exist_ok=True)
        self.low_objects = low
        low_path = os.path.join(root, "low", export.file_name(role_name(s.low_object, s.low_collection), ".glb"))
        parts = []
        try:
            for obj in low:
                arrays = export.low_arrays(obj, depsgraph, s.uv_map)
                if s.tangents == "BLENDER":
                    tangents, signs = blender_tangents(obj, depsgraph, arrays["uv_name"])
                    arrays["tangents"] = np.concatenate([tangents, signs[:, None]], axis=1)
                self.uv_names[obj.name] = arrays["uv_name"]
                self.quads += arrays["quads"]
                parts.append((obj.name, arrays))
            export.write_glb(low_path, parts)
            self.low_fingerprint = fingerprint(low + cage, depsgraph, s.uv_map)
            cage_path = None
            if cage:
                cage_path = os.path.join(root, "cage", export.file_name(role_name(s.cage_object, s.cage_collection), ".glb"))
                export.write_glb(cage_path, [(o.name, export.low_arrays(o, depsgraph, s.uv_map, need_uvs=False))
                                             for o in cage])
            t1 = time.perf_counter()
            high_paths = []
            for obj in high:
                path = os.path.join(root, "high", export.file_name(obj.name, ".ply"))
                stamp = fingerprint([obj], depsgraph)
                if _high_files.get(obj.name) != (path, stamp) or not os.path.isfile(path):
                    export.write_ply(path, export.high_arrays(obj, depsgraph))
                    _high_files[obj.name] = (path, stamp)
                high_paths.append(path)
        except ValueError as e:
            raise BakeError(str(e)) from None
        except OSError as e:
            raise BakeError("writing the meshes: %s" % e) from None
        t2 = time.perf_counter()
        self.timings["export_low"] = t1 - t0
        self.timings["export_high"] = t2 - t1
        self.timings["export"] = t2 - t0

        try:
            os.makedirs(out_dir, exist_ok=True)
        except OSError as e:
            raise BakeError("the output folder: %s" % e) from None
        keys = {
            "low": low_path,
            "high": high_paths,
            "outputs": [os.path.join(out_dir, template)],
            "size": int(s.size),
            "samples": int(s.samples),
            "maps": maps,
        }
        if s.preset != "NONE":
            keys["preset"] = s.preset.lower()
        if s.tangents == "BLENDER":
            keys["tangents"] = "file"
        if cage_path:
            keys["cage"] = cage_path
        if len(high_paths) == 1:
            # nmbake names a part-less file's part after its stem only among
            # several high files; one high object is every low part's high.
            keys["match"] = "off"
        self.request_keys = keys
        try:
            session = session_for(self.binary)
            self._sent = time.perf_counter()
            options = dict(keys)
            self.request = session.submit(options.pop("low"), options.pop("high"), options.pop("outputs"),
                                          progress=self._progress, **options)
        except client.Error as e:
            raise BakeError(str(e)) from None
        self.stage = "bake"
        self._thread = threading.Thread(target=self._wait, name="nmbake-blender-wait", daemon=True)
        self._thread.start()

    def cancel(self):
        if self.request is not None and not self.done:
            self.cancelled = True
            try:
                self.request.cancel()
            except client.Error:
                pass

    def wait(self):
        """Blocks until the bake has answered (the EXEC path)."""
        if self._thread is not None:
            self._thread.join()

    def finish(self, context):
        """Loads the maps as images and, when asked, wires the normal map
        into the low objects' materials. Returns the images by map name."""
        t0 = time.perf_counter()
        images = {}
        import bpy

        for entry in self.report.get("maps", []):
            for path in entry.get("outputs", []):
                name = os.path.basename(path)
                image = bpy.data.images.get(name)
                if image is not None and bpy.path.abspath(image.filepath) == path:
                    image.reload()
                else:
                    image = bpy.data.images.load(path, check_existing=False)
                    image.name = name
                image.colorspace_settings.name = "sRGB" if entry.get("map") in _COLOUR_MAPS else "Non-Color"
                images.setdefault(entry.get("map"), image)
        if self.settings.apply_material and "normal" in images:
            for obj in self.low_objects:
                wire_normal_map(obj, images["normal"], self.uv_names.get(obj.name, ""))
        self.timings["load"] = time.perf_counter() - t0
        return images

    # -- the waiting thread ----------------------------------------------

    def _progress(self, stage, fraction):
        self.stage = stage or self.stage
        self.fraction = float(fraction or 0.0)

    def _wait(self):
        try:
            self.report = self.request.result()
        except client.Cancelled as e:
            self.cancelled = True
            self.error = e
        except client.Error as e:
            self.error = e
        except Exception as e:  # noqa: BLE001 - shown to the user
            self.error = e
        finally:
            self.timings["bake"] = time.perf_counter() - self._sent
            self.done = True


def wire_normal_map(obj, image, uv_name):
    """An Image Texture (the map) into a Normal Map node (tangent space, the
    UV map baked with) into the Normal of each material's BSDF; a material
    is made when the object has none. Nodes are found again by name on a
    re-bake."""
    import bpy

    if not obj.material_slots or all(slot.material is None for slot in obj.material_slots):
        material = bpy.data.materials.new(obj.name + "_nmbake")
        material.use_nodes = True
        if obj.material_slots:
            obj.material_slots[0].material = material
        else:
            obj.data.materials.append(material)
    for slot in obj.material_slots:
        material = slot.material
        if material is None:
            continue
        material.use_nodes = True
        tree = material.node_tree
        nodes = tree.nodes
        bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
        if bsdf is None:
            output = next((n for n in nodes if n.type == "OUTPUT_MATERIAL"), None)
            if output is None or not output.inputs["Surface"].links:
                continue
            bsdf = output.inputs["Surface"].links[0].from_node
            if "Normal" not in bsdf.inputs:
                continue
        texture = nodes.get("nmbake normal map image") or nodes.new("ShaderNodeTexImage")
        texture.name = "nmbake normal map image"
        texture.image = image
        texture.interpolation = "Linear"
        texture.location = (bsdf.location.x - 600, bsdf.location.y - 400)
        normal_map = nodes.get("nmbake normal map") or nodes.new("ShaderNodeNormalMap")
        normal_map.name = "nmbake normal map"
        normal_map.space = "TANGENT"
        normal_map.uv_map = uv_name
        normal_map.location = (bsdf.location.x - 250, bsdf.location.y - 400)
        tree.links.new(texture.outputs["Color"], normal_map.inputs["Color"])
        tree.links.new(normal_map.outputs["Normal"], bsdf.inputs["Normal"])
