"""The Blender side of synthgen's `blender` backend, run inside the bpy interpreter that
synthgen-blender embeds through PyO3 (one interpreter per process, reused for every frame).

The scene is built once: one Blender object per (model primitive, instance slot), lights, the
ground plane, the camera and the world. Per frame only poses, lights, materials and the camera
change (`render_frame`), and `use_persistent_data` keeps Cycles' scene between renders.

Conventions (see crates/synthgen-blender/src/camera.rs): the Blender world frame IS the
OpenCV camera frame, scaled along y by fy / fx through the parent empty `synthgen_root`.
Every pose arrives from Rust already in that frame (cam_from_obj, light positions,
cam_from_plane); the camera's matrix_world (the only OpenCV <-> Blender rotation) is computed
in Rust. Nothing here converts conventions.
"""

import json

import bpy
import numpy as np
from mathutils import Matrix

_state = {}


def _linear(c):
    c = min(max(float(c), 0.0), 1.0)
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def setup(settings_json):
    """Empties the Blender session and sets up Cycles, the world, the camera and the root."""
    s = json.loads(settings_json)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(s["samples"])
    scene.cycles.use_denoising = bool(s["denoise"])
    if s["denoise"]:
        scene.cycles.denoiser = "OPENIMAGEDENOISE"
    scene.cycles.filter_width = float(s["filter_width_px"])
    scene.cycles.use_light_tree = True
    # BlenderProc's defaults for its BOP recipes: few bounces, no caustics.
    scene.cycles.max_bounces = 4
    scene.cycles.diffuse_bounces = 3
    scene.cycles.glossy_bounces = 3
    scene.cycles.transmission_bounces = 0
    scene.cycles.volume_bounces = 0
    scene.cycles.transparent_max_bounces = 2
    scene.cycles.caustics_reflective = False
    scene.cycles.caustics_refractive = False
    if int(s["threads"]) > 0:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = int(s["threads"])
    scene.render.use_persistent_data = True
    scene.render.film_transparent = True
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = 1.0
    scene.render.pixel_aspect_y = 1.0
    scene.render.use_file_extension = False
    scene.view_settings.view_transform = "Standard"
    im = scene.render.image_settings
    im.media_type = "MULTI_LAYER_IMAGE"
    im.file_format = "OPEN_EXR_MULTILAYER"
    im.color_depth = "32"
    im.exr_codec = "NONE"

    vl = scene.view_layers[0]
    vl.use_pass_z = True
    vl.use_pass_object_index = True

    world = bpy.data.worlds.new("synthgen_world")
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    bg.inputs["Strength"].default_value = 1.0
    # The environment light: `ground + (sky - ground) * [dir . up > 0]`, each scaled by the
    # ambient (the raster's two-colour hemisphere probe; a uniform world when sky = ground).
    # A world shader's Generated coordinate is the view direction in world space.
    wt = world.node_tree
    coord = wt.nodes.new("ShaderNodeTexCoord")
    up_dot = wt.nodes.new("ShaderNodeVectorMath")
    up_dot.operation = "DOT_PRODUCT"
    wt.links.new(coord.outputs["Generated"], up_dot.inputs[0])
    above = wt.nodes.new("ShaderNodeMath")
    above.operation = "GREATER_THAN"
    above.inputs[1].default_value = 0.0
    wt.links.new(up_dot.outputs["Value"], above.inputs[0])
    sky_minus_ground = wt.nodes.new("ShaderNodeVectorMath")
    sky_minus_ground.operation = "SCALE"
    wt.links.new(above.outputs["Value"], sky_minus_ground.inputs["Scale"])
    env = wt.nodes.new("ShaderNodeVectorMath")
    env.operation = "ADD"
    wt.links.new(sky_minus_ground.outputs["Vector"], env.inputs[0])
    wt.links.new(env.outputs["Vector"], bg.inputs["Color"])

    cam = bpy.data.objects.new("synthgen_camera", bpy.data.cameras.new("synthgen_camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.data.sensor_fit = "HORIZONTAL"
    cam.data.clip_start = 0.01
    cam.data.clip_end = 1000.0

    root = bpy.data.objects.new("synthgen_root", None)
    scene.collection.objects.link(root)

    ground = _make_ground(scene, root)
    _state.clear()
    _state.update(
        scene=scene,
        root=root,
        camera=cam,
        world_up=up_dot,
        world_diff=sky_minus_ground,
        world_ground=env,
        ground=ground,
        models={},  # model_index -> list of (mesh, base material, material kind)
        instances={},  # model_index -> list of instance slots (lists of objects)
        lights=[],
        walls=[],
        surface_images={},  # "ground" / "walls" -> list of bpy images
    )


def _plane_material(name):
    """A principled material whose base colour is either the procedural checker (`tiles`,
    the ground without an image) or an image tiled through a mapping node times a colour
    (`image`, `mapping`, `tint`, `mul`); `_use_image` links one of the two."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes.get("Principled BSDF")
    bsdf.inputs["Roughness"].default_value = 0.8
    coords = nt.nodes.new("ShaderNodeTexCoord")
    checker = nt.nodes.new("ShaderNodeTexChecker")
    checker.name = "tiles"
    nt.links.new(coords.outputs["Object"], checker.inputs["Vector"])
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.name = "mapping"
    mapping.vector_type = "POINT"
    nt.links.new(coords.outputs["Object"], mapping.inputs["Vector"])
    image = nt.nodes.new("ShaderNodeTexImage")
    image.name = "image"
    image.extension = "REPEAT"
    image.interpolation = "Closest"
    nt.links.new(mapping.outputs["Vector"], image.inputs["Vector"])
    tint = nt.nodes.new("ShaderNodeRGB")
    tint.name = "tint"
    mul = nt.nodes.new("ShaderNodeVectorMath")
    mul.name = "mul"
    mul.operation = "MULTIPLY"
    nt.links.new(image.outputs["Color"], mul.inputs[0])
    nt.links.new(tint.outputs["Color"], mul.inputs[1])
    nt.links.new(checker.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def _use_image(mat, kind, t, color):
    """Links the material's base colour to image `t["image"]` of `kind` (tiled by
    `t["scale"]`, offset by `t["offset"]`, in the plane object's coordinates) times `color`,
    or, when `t` is None, to the checker."""
    nt = mat.node_tree
    bsdf = nt.nodes.get("Principled BSDF")
    if t is None:
        nt.links.new(nt.nodes["tiles"].outputs["Color"], bsdf.inputs["Base Color"])
        return
    nt.nodes["image"].image = _state["surface_images"][kind][int(t["image"])]
    m = nt.nodes["mapping"]
    m.inputs["Scale"].default_value = (t["scale"][0], t["scale"][1], 1.0)
    m.inputs["Location"].default_value = (t["offset"][0], t["offset"][1], 0.0)
    nt.nodes["tint"].outputs["Color"].default_value = (*[_linear(x) for x in color], 1.0)
    nt.links.new(nt.nodes["mul"].outputs["Vector"], bsdf.inputs["Base Color"])


def _unit_square(name):
    me = bpy.data.meshes.new(name)
    me.from_pydata([(-0.5, -0.5, 0), (0.5, -0.5, 0), (0.5, 0.5, 0), (-0.5, 0.5, 0)], [], [(0, 1, 2, 3)])
    me.update()
    return me


def _make_ground(scene, root):
    me = _unit_square("synthgen_ground")
    me.materials.append(_plane_material("synthgen_ground"))
    obj = bpy.data.objects.new("synthgen_ground", me)
    scene.collection.objects.link(obj)
    obj.parent = root
    obj.pass_index = 0
    obj.hide_render = True
    return obj


def _wall(i):
    """Wall object `i` (a unit square with its own material), created on first use."""
    walls = _state["walls"]
    while len(walls) <= i:
        name = "synthgen_wall.%d" % len(walls)
        me = _unit_square(name)
        me.materials.append(_plane_material(name))
        obj = bpy.data.objects.new(name, me)
        _state["scene"].collection.objects.link(obj)
        obj.parent = _state["root"]
        obj.pass_index = 0
        walls.append(obj)
    return walls[i]


def add_surface_image(kind, width, height, rgb):
    """Image number len(list) of `kind` ("ground" or "walls"): sRGB bytes, top row first."""
    images = _state["surface_images"].setdefault(kind, [])
    px = np.frombuffer(rgb, dtype=np.uint8).reshape(height, width, 3)[::-1]
    rgba = np.ones((height, width, 4), dtype=np.float32)
    rgba[:, :, :3] = px / 255.0
    img = bpy.data.images.new("synthgen_%s.%d" % (kind, len(images)), width, height, alpha=False)
    img.pixels.foreach_set(rgba.ravel())
    img.pack()
    images.append(img)


def add_primitive(model_index, name, positions, triangles, normals, colors, uvs, texture, material_json):
    """One primitive of model `model_index` (metres, object frame). Arrays are little-endian
    bytes: positions and normals f32 x3, triangles u32 x3, colors u8 sRGB x3, uvs f32 x2
    (v = 0 is the texture's top row); texture is (width, height, sRGB bytes top row first)."""
    m = json.loads(material_json)
    pos = np.frombuffer(positions, dtype="<f4").reshape(-1, 3)
    tri = np.frombuffer(triangles, dtype="<u4").reshape(-1, 3)
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(pos))
    me.vertices.foreach_set("co", pos.ravel())
    me.loops.add(tri.size)
    me.loops.foreach_set("vertex_index", tri.ravel().astype(np.int32))
    me.polygons.add(len(tri))
    me.polygons.foreach_set("loop_start", np.arange(0, tri.size, 3, dtype=np.int32))
    me.update()
    if normals is not None:
        nrm = np.frombuffer(normals, dtype="<f4").reshape(-1, 3)
        me.shade_smooth()
        me.normals_split_custom_set_from_vertices(nrm.tolist())

    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes.get("Principled BSDF")
    tint = nt.nodes.new("ShaderNodeRGB")
    tint.name = "tint"
    mul = nt.nodes.new("ShaderNodeVectorMath")
    mul.operation = "MULTIPLY"
    source = None
    if uvs is not None and texture is not None:
        uv = np.frombuffer(uvs, dtype="<f4").reshape(-1, 2).copy()
        uv[:, 1] = 1.0 - uv[:, 1]  # Blender's v = 0 is the bottom row
        layer = me.uv_layers.new(name="UVMap")
        layer.data.foreach_set("uv", uv[tri.ravel()].ravel())
        tw, th, tbytes = texture
        px = np.frombuffer(tbytes, dtype=np.uint8).reshape(th, tw, 3)[::-1]
        rgba = np.ones((th, tw, 4), dtype=np.float32)
        rgba[:, :, :3] = px / 255.0
        img = bpy.data.images.new(name + "_tex", tw, th, alpha=False)
        img.pixels.foreach_set(rgba.ravel())
        img.pack()
        node = nt.nodes.new("ShaderNodeTexImage")
        node.image = img
        source = node.outputs["Color"]
    elif colors is not None:
        col = np.frombuffer(colors, dtype=np.uint8).reshape(-1, 3)
        rgba = np.ones((len(col), 4), dtype=np.float32)
        rgba[:, :3] = col / 255.0
        attr = me.color_attributes.new("Col", "BYTE_COLOR", "POINT")
        attr.data.foreach_set("color_srgb", rgba.ravel())
        node = nt.nodes.new("ShaderNodeVertexColor")
        node.layer_name = "Col"
        source = node.outputs["Color"]
    if source is not None:
        nt.links.new(source, mul.inputs[0])
        nt.links.new(tint.outputs["Color"], mul.inputs[1])
        nt.links.new(mul.outputs["Vector"], bsdf.inputs["Base Color"])
    else:
        nt.links.new(tint.outputs["Color"], bsdf.inputs["Base Color"])
    base = [_linear(c) for c in m["base_color"]]
    tint.outputs["Color"].default_value = (*base, 1.0)
    me.materials.append(mat)
    _state["models"].setdefault(int(model_index), []).append((me, mat, base))


def _instance(model_index, slot):
    """The objects of instance `slot` of a model, created (with its own materials) on first use."""
    slots = _state["instances"].setdefault(model_index, [])
    while len(slots) <= slot:
        objs = []
        for me, mat, _ in _state["models"][model_index]:
            obj = bpy.data.objects.new("%s.%d" % (me.name, len(slots)), me)
            _state["scene"].collection.objects.link(obj)
            obj.parent = _state["root"]
            obj.material_slots[0].link = "OBJECT"
            obj.material_slots[0].material = mat.copy()
            objs.append(obj)
        slots.append(objs)
    return slots[slot]


def _light(i):
    lights = _state["lights"]
    while len(lights) <= i:
        data = bpy.data.lights.new("synthgen_light.%d" % len(lights), "POINT")
        data.shadow_soft_size = 0.0
        data.use_soft_falloff = False
        obj = bpy.data.objects.new(data.name, data)
        _state["scene"].collection.objects.link(obj)
        obj.parent = _state["root"]
        lights.append(obj)
    return lights[i]


def _matrix(rows):
    return Matrix([list(r) for r in rows])


def render_frame(frame_json, exr_path):
    """Poses, lights, materials and camera of one frame; renders Combined, Z and Object Index
    into the multilayer EXR `exr_path`."""
    f = json.loads(frame_json)
    scene = _state["scene"]
    c = f["camera"]
    scene.render.resolution_x = int(c["width"])
    scene.render.resolution_y = int(c["height"])
    cam = _state["camera"]
    cam.data.lens = c["lens_mm"]
    cam.data.sensor_width = c["sensor_width_mm"]
    cam.data.shift_x = c["shift_x"]
    cam.data.shift_y = c["shift_y"]
    cam.matrix_world = _matrix(c["matrix_world"])
    _state["root"].scale = (1.0, c["y_scale"], 1.0)
    scene.cycles.seed = int(f["seed"]) & 0x7FFFFFFF

    used = {}
    for o in f["objects"]:
        mi = int(o["model_index"])
        slot = used.get(mi, 0)
        used[mi] = slot + 1
        for obj, (_, _, base) in zip(_instance(mi, slot), _state["models"][mi]):
            obj.hide_render = False
            obj.pass_index = int(o["pass_index"])
            obj.matrix_parent_inverse = Matrix.Identity(4)
            obj.matrix_basis = _matrix(o["matrix"])
            nt = obj.material_slots[0].material.node_tree
            b = float(o["brightness"])
            t = o.get("tint", [1.0, 1.0, 1.0])
            # Hue rotation (linear RGB, about the grey axis) of the material's base colour:
            # exact for plain-coloured models; vertex colours and textures keep their hue.
            m = o.get("hue_matrix", [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
            rb = [max(0.0, sum(m[i][j] * base[j] for j in range(3))) for i in range(3)]
            nt.nodes["tint"].outputs["Color"].default_value = (rb[0] * b * t[0], rb[1] * b * t[1], rb[2] * b * t[2], 1.0)
            bsdf = nt.nodes["Principled BSDF"]
            bsdf.inputs["Roughness"].default_value = o["roughness"]
            bsdf.inputs["Specular IOR Level"].default_value = o["specular_ior_level"]
            bsdf.inputs["Metallic"].default_value = o.get("metallic", 0.0)
    for mi, slots in _state["instances"].items():
        for objs in slots[used.get(mi, 0):]:
            for obj in objs:
                obj.hide_render = True

    for i, l in enumerate(f["lights"]):
        obj = _light(i)
        obj.hide_render = False
        obj.matrix_parent_inverse = Matrix.Identity(4)
        obj.matrix_basis = Matrix.Translation(l["position"])
        obj.data.color = l["color"]
        obj.data.energy = l["power_w"]
    for obj in _state["lights"][len(f["lights"]):]:
        obj.hide_render = True

    a = f["ambient"]
    e = f.get("environment") or {"sky": [1.0] * 3, "ground": [1.0] * 3, "up": [0.0, -1.0, 0.0]}
    _state["world_up"].inputs[1].default_value = e["up"]
    _state["world_diff"].inputs[0].default_value = [a * (s - g) for s, g in zip(e["sky"], e["ground"])]
    _state["world_ground"].inputs[1].default_value = [a * g for g in e["ground"]]

    g = f["ground"]
    ground = _state["ground"]
    ground.hide_render = g is None
    if g is not None:
        ground.matrix_parent_inverse = Matrix.Identity(4)
        ground.matrix_basis = _matrix(g["matrix"]) @ Matrix.Diagonal((g["size_m"], g["size_m"], 1.0, 1.0))
        mat = ground.material_slots[0].material
        tiles = mat.node_tree.nodes["tiles"]
        col = [_linear(x) for x in g["color"]]
        k = g["texture_strength"]
        tiles.inputs["Color1"].default_value = (*[x * (1.0 - k) for x in col], 1.0)
        tiles.inputs["Color2"].default_value = (*[x * (1.0 + k) for x in col], 1.0)
        tiles.inputs["Scale"].default_value = g["size_m"] / 0.04
        _use_image(mat, "ground", g.get("texture"), g["color"])

    walls = f.get("walls", [])
    for i, w in enumerate(walls):
        obj = _wall(i)
        obj.hide_render = False
        obj.matrix_parent_inverse = Matrix.Identity(4)
        obj.matrix_basis = _matrix(w["matrix"]) @ Matrix.Diagonal((w["width_m"], w["height_m"], 1.0, 1.0))
        mat = obj.material_slots[0].material
        if w.get("texture") is None:
            # A plain wall: the checker with both colours equal.
            tiles = mat.node_tree.nodes["tiles"]
            col = (*[_linear(x) for x in w["color"]], 1.0)
            tiles.inputs["Color1"].default_value = col
            tiles.inputs["Color2"].default_value = col
        _use_image(mat, "walls", w.get("texture"), w["color"])
    for obj in _state["walls"][len(walls):]:
        obj.hide_render = True

    scene.render.filepath = exr_path
    bpy.ops.render.render(write_still=True)
