//! Rasterization of one object into its own window: a depth buffer (stored as 1/z while
//! drawing) and the id of the nearest triangle per pixel. This is the object's "alone"
//! render; the frame composites these windows afterwards.
//!
//! Vertices are snapped to 1/256 pixel and edge functions are evaluated exactly in integers,
//! so shared edges never crack or double-cover, and the top-left rule decides pixel centres
//! that lie exactly on an edge.

use synthgen_core::glam::{Mat3, Vec3};

use crate::bits::select;
use crate::prepare::PreparedModel;

/// Sub-pixel bits of the fixed-point screen coordinates.
const SUB_BITS: u32 = 8;
const SUB: i32 = 1 << SUB_BITS;
/// Vertices projecting further than this from the image origin (pixels) are clipped in 3D
/// first, which keeps every edge-function product inside i64.
const GUARD_PX: f32 = 1_048_576.0;

/// A projected vertex: fixed-point pixel coordinates and 1/z. `iz <= 0` marks a vertex that
/// is in front of the near plane or beyond the guard band; its triangles take the clipping
/// path.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ScreenVert {
    pub x: i32,
    pub y: i32,
    pub iz: f32,
}

/// Pinhole projection in f32 plus the near plane.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Projection {
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub near_m: f32,
}

impl Projection {
    /// The camera-frame point at z-depth `z` seen through the centre of pixel (x, y).
    #[inline(always)]
    pub(crate) fn unproject(&self, x: f32, y: f32, z: f32) -> Vec3 {
        Vec3::new(
            (x + 0.5 - self.cx) / self.fx * z,
            (y + 0.5 - self.cy) / self.fy * z,
            z,
        )
    }

    #[inline(always)]
    fn project(&self, p: Vec3) -> ScreenVert {
        let iz = 1.0 / p.z;
        let sx = self.fx * p.x * iz + self.cx;
        let sy = self.fy * p.y * iz + self.cy;
        if p.z >= self.near_m && sx.abs() < GUARD_PX && sy.abs() < GUARD_PX {
            ScreenVert {
                x: round_fixed(sx),
                y: round_fixed(sy),
                iz,
            }
        } else {
            ScreenVert {
                x: 0,
                y: 0,
                iz: -1.0,
            }
        }
    }
}

/// A half-open pixel rectangle `[x0, x1) x [y0, y1)` in image pixel coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Rect {
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
}

/// The canvas for alone renders (three times the image, centred on it) and the image.
pub(crate) fn canvas_and_image(k: &synthgen_core::Intrinsics) -> (Rect, Rect) {
    let (wi, hi) = (k.width as i32, k.height as i32);
    let canvas = Rect {
        x0: -wi,
        y0: -hi,
        x1: 2 * wi,
        y1: 2 * hi,
    };
    let image = Rect {
        x0: 0,
        y0: 0,
        x1: wi,
        y1: hi,
    };
    (canvas, image)
}

impl Rect {
    pub fn width(&self) -> usize {
        (self.x1 - self.x0).max(0) as usize
    }
    pub fn height(&self) -> usize {
        (self.y1 - self.y0).max(0) as usize
    }
    pub fn is_empty(&self) -> bool {
        self.x1 <= self.x0 || self.y1 <= self.y0
    }
    pub fn intersect(&self, o: &Rect) -> Rect {
        Rect {
            x0: self.x0.max(o.x0),
            y0: self.y0.max(o.y0),
            x1: self.x1.min(o.x1),
            y1: self.y1.min(o.y1),
        }
    }
}

/// Running bounding box of fixed-point vertices.
#[derive(Debug, Clone, Copy)]
struct FixedBounds {
    min: [i32; 2],
    max: [i32; 2],
}

impl FixedBounds {
    const EMPTY: FixedBounds = FixedBounds {
        min: [i32::MAX; 2],
        max: [i32::MIN; 2],
    };
    #[inline(always)]
    fn add(&mut self, v: ScreenVert) {
        self.min = [self.min[0].min(v.x), self.min[1].min(v.y)];
        self.max = [self.max[0].max(v.x), self.max[1].max(v.y)];
    }
    /// Pixels whose centre lies inside the box.
    fn pixel_rect(&self) -> Rect {
        if self.min[0] > self.max[0] {
            return Rect::default();
        }
        Rect {
            x0: ceil_px(self.min[0]),
            y0: ceil_px(self.min[1]),
            x1: floor_px(self.max[0]) + 1,
            y1: floor_px(self.max[1]) + 1,
        }
    }
}

#[inline(always)]
fn ceil_px(v: i32) -> i32 {
    (v + (SUB - 1)) >> SUB_BITS
}

#[inline(always)]
fn floor_px(v: i32) -> i32 {
    v >> SUB_BITS
}

/// A triangle (or a piece of one, after clipping) ready to rasterize.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ClippedTri {
    v: [ScreenVert; 3],
    id: u32,
    cull: bool,
}

/// Per-object buffers reused across frames.
#[derive(Debug, Default)]
pub(crate) struct ObjScratch {
    pub verts: Vec<ScreenVert>,
    /// Nearest triangle per window pixel; valid where the depth is > 0.
    pub ids: Vec<u32>,
    pub window: Rect,
    clipped: Vec<ClippedTri>,
    /// Triangle ids surviving culling, by bounding-box size.
    singles: Vec<u32>,
    multis: Vec<u32>,
}

/// Projects every vertex of `model` into `verts` (fixed point, 1/z; `iz = -1` marks a vertex
/// that needs clipping). Branch-free and free of libm calls, so it vectorizes.
fn transform_vertices(
    model: &PreparedModel,
    rot: &Mat3,
    t: Vec3,
    proj: &Projection,
    verts: &mut Vec<ScreenVert>,
) {
    let (c0, c1, c2) = (rot.x_axis, rot.y_axis, rot.z_axis);
    verts.clear();
    verts.resize(model.xs.len(), ScreenVert::default());
    for (((v, &x), &y), &z) in verts
        .iter_mut()
        .zip(&model.xs)
        .zip(&model.ys)
        .zip(&model.zs)
    {
        let px = c0.x * x + c1.x * y + c2.x * z + t.x;
        let py = c0.y * x + c1.y * y + c2.y * z + t.y;
        let pz = c0.z * x + c1.z * y + c2.z * z + t.z;
        let iz = 1.0 / pz;
        let sx = proj.fx * px * iz + proj.cx;
        let sy = proj.fy * py * iz + proj.cy;
        let ok = (pz >= proj.near_m) & (sx.abs() < GUARD_PX) & (sy.abs() < GUARD_PX);
        *v = ScreenVert {
            x: if ok { round_fixed(sx) } else { 0 },
            y: if ok { round_fixed(sy) } else { 0 },
            iz: if ok { iz } else { -1.0 },
        };
    }
}

/// `round(v * 2^SUB_BITS)` for |v| < 2^20 through the f64 mantissa (1.5 * 2^52 leaves the
/// rounded integer in the low bits) instead of a libm `roundf` call.
#[inline(always)]
fn round_fixed(v: f32) -> i32 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    (v as f64 * SUB as f64 + MAGIC).to_bits() as u32 as i32
}

/// Rasterizes `model` at `cam_from_obj` into `depth` (resized to the window, row-major, z in
/// metres, 0 where uncovered) and `scratch.ids`. The window is the projected bounding box of
/// the model clipped to `canvas`. Returns the window. With `all_faces`, no triangle is culled
/// for facing away (as an OpenGL pipeline without face culling draws).
#[allow(clippy::too_many_arguments)]
pub(crate) fn raster_object(
    model: &PreparedModel,
    all_faces: bool,
    rot: &Mat3,
    t: Vec3,
    proj: &Projection,
    canvas: Rect,
    scratch: &mut ObjScratch,
    depth: &mut Vec<f32>,
) -> Rect {
    let ObjScratch {
        verts,
        ids,
        window,
        clipped,
        singles,
        multis,
    } = scratch;
    clipped.clear();
    let (c0, c1, c2) = (rot.x_axis, rot.y_axis, rot.z_axis);
    transform_vertices(model, rot, t, proj, verts);
    let mut bounds = FixedBounds::EMPTY;
    let mut any_clipped = false;
    for v in verts.iter() {
        let ok = v.iz > 0.0;
        // Selects, not branches, so this vectorizes.
        bounds.min[0] = bounds.min[0].min(if ok { v.x } else { i32::MAX });
        bounds.min[1] = bounds.min[1].min(if ok { v.y } else { i32::MAX });
        bounds.max[0] = bounds.max[0].max(if ok { v.x } else { i32::MIN });
        bounds.max[1] = bounds.max[1].max(if ok { v.y } else { i32::MIN });
        any_clipped |= !ok;
    }
    if any_clipped {
        for prim in &model.prims {
            let cull = !prim.double_sided && !all_faces;
            for id in prim.tri_start..prim.tri_end {
                let tri = model.tris[id as usize];
                if tri.iter().all(|&i| verts[i as usize].iz > 0.0) {
                    continue;
                }
                let p = tri.map(|i| {
                    c0 * model.xs[i as usize]
                        + c1 * model.ys[i as usize]
                        + c2 * model.zs[i as usize]
                        + t
                });
                clip_triangle(p, proj, id, cull, clipped);
            }
        }
        for c in clipped.iter() {
            for v in c.v {
                bounds.add(v);
            }
        }
    }
    *window = bounds.pixel_rect().intersect(&canvas);
    depth.clear();
    if window.is_empty() {
        *window = Rect::default();
        return *window;
    }
    let n = window.width() * window.height();
    depth.resize(n, 0.0);
    if ids.len() < n {
        ids.resize(n, 0);
    }
    let mut target = Target {
        window: *window,
        stride: window.width(),
        invz: &mut depth[..],
        ids: &mut ids[..n],
    };
    // Pixel-centre limits, inclusive.
    let lim = Rect {
        x0: window.x0,
        y0: window.y0,
        x1: window.x1 - 1,
        y1: window.y1 - 1,
    };
    // Pass 1, branch-free over every triangle: keep those facing the camera whose bounding
    // box holds a pixel centre, split into single-centre boxes (most, for scanned meshes)
    // and the rest. Unpredictable branches per triangle would cost more than the work.
    let nt = model.tris.len();
    singles.resize(nt, 0);
    multis.resize(nt, 0);
    let (mut ns, mut nm) = (0usize, 0usize);
    // The camera in the object frame, for culling whole clusters that face away.
    let eye = -(rot.transpose() * t);
    for cl in &model.clusters {
        if !all_faces && cl.faces_away(eye) {
            continue;
        }
        let cull = !cl.double_sided && !all_faces;
        let tris = &model.tris[cl.start as usize..cl.end as usize];
        for (id, tri) in (cl.start..).zip(tris) {
            let a = verts[tri[0] as usize];
            let b = verts[tri[1] as usize];
            let c = verts[tri[2] as usize];
            // Triangles with a clipped vertex are drawn from `clipped`.
            let in_front = (a.iz > 0.0) & (b.iz > 0.0) & (c.iz > 0.0);
            let px0 = ceil_px(a.x.min(b.x).min(c.x)).max(lim.x0);
            let px1 = floor_px(a.x.max(b.x).max(c.x)).min(lim.x1);
            let py0 = ceil_px(a.y.min(b.y).min(c.y)).max(lim.y0);
            let py1 = floor_px(a.y.max(b.y).max(c.y)).min(lim.y1);
            let area = signed_area(a, b, c);
            let facing = (area < 0) | ((area > 0) & !cull);
            let keep = in_front & facing & (px0 <= px1) & (py0 <= py1);
            let single = (px0 == px1) & (py0 == py1);
            singles[ns] = id;
            ns += (keep & single) as usize;
            multis[nm] = id;
            nm += (keep & !single) as usize;
        }
    }
    // Pass 2: one candidate pixel each: three edge functions at that pixel.
    for &id in &singles[..ns] {
        let tri = model.tris[id as usize];
        let (a, b, c) = (
            verts[tri[0] as usize],
            verts[tri[1] as usize],
            verts[tri[2] as usize],
        );
        let (px, py) = (
            ceil_px(a.x.min(b.x).min(c.x)).max(lim.x0),
            ceil_px(a.y.min(b.y).min(c.y)).max(lim.y0),
        );
        let area = signed_area(a, b, c);
        // Orient counter-clockwise in the y-down image (positive area), as `raster_tri`.
        let front = area < 0;
        let (b, c) = if front { (c, b) } else { (b, c) };
        let area = area.abs();
        let (e0, _, _, l0) = edge(b, c, px, py);
        let (e1, _, _, l1) = edge(c, a, px, py);
        let (e2, _, _, l2) = edge(a, b, px, py);
        // A branch beats a select here: skipping the store for uncovered pixels avoids
        // read-modify-write chains through the depth buffer.
        if (e0 > l0) & (e1 > l1) & (e2 > l2) {
            let invz = (e0 as f32 * a.iz + e1 as f32 * b.iz + e2 as f32 * c.iz) / area as f32;
            target.write(px, py, invz, id);
        }
    }
    // Pass 3: larger triangles, scanned over their boxes.
    for &id in &multis[..nm] {
        let tri = model.tris[id as usize];
        let (a, b, c) = (
            verts[tri[0] as usize],
            verts[tri[1] as usize],
            verts[tri[2] as usize],
        );
        // Culling already done: only orientation matters here.
        raster_tri(a, b, c, id, false, &lim, &mut target);
    }
    for c in clipped.iter() {
        raster_tri(c.v[0], c.v[1], c.v[2], c.id, c.cull, &lim, &mut target);
    }
    for d in depth.iter_mut() {
        *d = select(*d > 0.0, 1.0 / *d, 0.0);
    }
    *window
}

struct Target<'a> {
    window: Rect,
    stride: usize,
    /// 1/z while drawing (0 = empty, larger = nearer).
    invz: &'a mut [f32],
    ids: &'a mut [u32],
}

impl Target<'_> {
    #[inline(always)]
    fn write(&mut self, px: i32, py: i32, invz: f32, id: u32) {
        let i = (py - self.window.y0) as usize * self.stride + (px - self.window.x0) as usize;
        if invz > self.invz[i] {
            self.invz[i] = invz;
            self.ids[i] = id;
        }
    }
}

/// Twice the signed area of the projected triangle (fixed point squared); negative for a
/// front face (counter-clockwise seen from outside reads clockwise with y down).
#[inline(always)]
fn signed_area(a: ScreenVert, b: ScreenVert, c: ScreenVert) -> i64 {
    (b.x - a.x) as i64 * (c.y - a.y) as i64 - (b.y - a.y) as i64 * (c.x - a.x) as i64
}

/// Edge function of the directed edge p -> q at pixel centre (px, py), its per-pixel steps,
/// and the value it must exceed (top-left rule: 0 on a top or left edge counts as inside).
#[inline(always)]
fn edge(p: ScreenVert, q: ScreenVert, px: i32, py: i32) -> (i64, i64, i64, i64) {
    let ex = (q.x - p.x) as i64;
    let ey = (q.y - p.y) as i64;
    let sx = ((px << SUB_BITS) - p.x) as i64;
    let sy = ((py << SUB_BITS) - p.y) as i64;
    let e = ex * sy - ey * sx;
    let (dx, dy) = (-ey, ex);
    let top_left = dx > 0 || (dx == 0 && dy > 0);
    (
        e,
        dx << SUB_BITS,
        dy << SUB_BITS,
        if top_left { -1 } else { 0 },
    )
}

/// Draws one triangle: pixel (px, py) is covered iff its centre is inside (top-left rule for
/// centres on an edge). Triangles facing away are culled when `cull`; front faces are
/// counter-clockwise seen from outside, which in the y-down image reads as a negative
/// signed area.
#[inline(always)]
fn raster_tri(
    a: ScreenVert,
    b: ScreenVert,
    c: ScreenVert,
    id: u32,
    cull: bool,
    lim: &Rect,
    tgt: &mut Target,
) {
    let px0 = ceil_px(a.x.min(b.x).min(c.x)).max(lim.x0);
    let px1 = floor_px(a.x.max(b.x).max(c.x)).min(lim.x1);
    if px0 > px1 {
        return;
    }
    let py0 = ceil_px(a.y.min(b.y).min(c.y)).max(lim.y0);
    let py1 = floor_px(a.y.max(b.y).max(c.y)).min(lim.y1);
    if py0 > py1 {
        return;
    }
    let area = signed_area(a, b, c);
    // Orient so that the interior is where all edge functions are positive.
    let (b, c, area) = if area < 0 {
        (c, b, -area)
    } else if area > 0 && !cull {
        (b, c, area)
    } else {
        return;
    };
    let (e0, dx0, dy0, l0) = edge(b, c, px0, py0); // weight of a
    let (e1, dx1, dy1, l1) = edge(c, a, px0, py0); // weight of b
    let (e2, dx2, dy2, l2) = edge(a, b, px0, py0); // weight of c
    if px0 == px1 && py0 == py1 {
        if (e0 > l0) & (e1 > l1) & (e2 > l2) {
            let invz = (e0 as f32 * a.iz + e1 as f32 * b.iz + e2 as f32 * c.iz) / area as f32;
            tgt.write(px0, py0, invz, id);
        }
        return;
    }
    let inv_area = 1.0 / area as f32;
    let (mut r0, mut r1, mut r2) = (e0, e1, e2);
    for py in py0..=py1 {
        let (mut w0, mut w1, mut w2) = (r0, r1, r2);
        for px in px0..=px1 {
            if (w0 > l0) & (w1 > l1) & (w2 > l2) {
                let invz = (w0 as f32 * a.iz + w1 as f32 * b.iz + w2 as f32 * c.iz) * inv_area;
                tgt.write(px, py, invz, id);
            }
            w0 += dx0;
            w1 += dx1;
            w2 += dx2;
        }
        r0 += dy0;
        r1 += dy1;
        r2 += dy2;
    }
}

/// Clips a camera-space triangle against the near plane and the guard band
/// (Sutherland-Hodgman), projects the polygon and fans it into `out`.
fn clip_triangle(p: [Vec3; 3], proj: &Projection, id: u32, cull: bool, out: &mut Vec<ClippedTri>) {
    // Slightly inside the guard so projected vertices pass it despite rounding.
    let g = GUARD_PX * 0.99;
    // Each plane keeps points with dot(n, p) + d >= 0.
    let planes = [
        (Vec3::Z, -proj.near_m),
        (Vec3::new(-proj.fx, 0.0, g - proj.cx), 0.0),
        (Vec3::new(proj.fx, 0.0, g + proj.cx), 0.0),
        (Vec3::new(0.0, -proj.fy, g - proj.cy), 0.0),
        (Vec3::new(0.0, proj.fy, g + proj.cy), 0.0),
    ];
    let mut poly: Vec<Vec3> = p.to_vec();
    let mut next: Vec<Vec3> = Vec::with_capacity(8);
    for (n, d) in planes {
        next.clear();
        for i in 0..poly.len() {
            let (s, e) = (poly[i], poly[(i + 1) % poly.len()]);
            let (ds, de) = (n.dot(s) + d, n.dot(e) + d);
            if ds >= 0.0 {
                next.push(s);
            }
            if (ds >= 0.0) != (de >= 0.0) {
                let t = ds / (ds - de);
                let mut q = s + (e - s) * t;
                if n == Vec3::Z {
                    q.z = q.z.max(proj.near_m); // exactly on the plane, not a hair before it
                }
                next.push(q);
            }
        }
        std::mem::swap(&mut poly, &mut next);
        if poly.len() < 3 {
            return;
        }
    }
    let sv: Vec<ScreenVert> = poly.iter().map(|&q| proj.project(q)).collect();
    if sv.iter().any(|v| v.iz <= 0.0) {
        return; // degenerate sliver lost to rounding
    }
    for i in 1..sv.len() - 1 {
        out.push(ClippedTri {
            v: [sv[0], sv[i], sv[i + 1]],
            id,
            cull,
        });
    }
}
