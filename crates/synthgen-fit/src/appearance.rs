//! Whether a pose puts the model's own colours where the image has them: the model's vertex
//! colours (or texture) rasterized at the pose and correlated with the image's pixels under
//! it. Edges alone cannot tell an object from itself turned by 180° when the two outlines
//! look alike (a duck from either side, a watering can front and back); the colours inside
//! the outline can. [`crate::edge_refine`] uses it to choose among refined poses whose edge
//! costs are close.

use synthgen_core::glam::{DVec2, DVec3};
use synthgen_core::{Intrinsics, Model, Pose};

use crate::raster::{project, sobel, to_object, Rect, ZBuffer};
use crate::region::RegionColours;

/// A model's triangles (object frame, metres) with each corner's sRGB colour (0..1): from
/// its vertex colours, else its texture at the corner's texture coordinate, else its base
/// colour, times the base colour.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ColouredSurface {
    pub triangles: Vec<[DVec3; 3]>,
    pub colours: Vec<[[f32; 3]; 3]>,
}

/// Fewer sampled pixels than this and a pose's colours say nothing.
const MIN_PIXELS: usize = 30;

impl ColouredSurface {
    /// None when the model's colours hardly vary (standard deviation under 0.02 in every
    /// channel over its corners): one flat colour cannot tell one side from another.
    pub fn from_model(model: &Model) -> Option<ColouredSurface> {
        let mut out = ColouredSurface::default();
        for p in &model.primitives {
            let base = p.material.base_color;
            let corner = |i: usize| -> [f32; 3] {
                let c = if let Some(c) = p.colors.as_ref().and_then(|c| c.get(i)) {
                    *c
                } else if let (Some(t), Some(uv)) =
                    (&p.material.texture, p.uvs.as_ref().and_then(|uv| uv.get(i)))
                {
                    let (w, h) = (t.width.max(1) as i64, t.height.max(1) as i64);
                    let x = ((f64::from(uv.x) * w as f64).floor() as i64).rem_euclid(w) as usize;
                    let y = ((f64::from(uv.y) * h as f64).floor() as i64).rem_euclid(h) as usize;
                    let o = (y * w as usize + x) * 3;
                    match t.rgb.get(o..o + 3) {
                        Some(px) => [px[0], px[1], px[2]].map(|v| f32::from(v) / 255.0),
                        None => [1.0; 3],
                    }
                } else {
                    [1.0; 3]
                };
                [c[0] * base[0], c[1] * base[1], c[2] * base[2]]
            };
            for t in &p.triangles {
                let idx = t.map(|i| i as usize);
                let (Some(a), Some(b), Some(c)) = (
                    p.positions_m.get(idx[0]),
                    p.positions_m.get(idx[1]),
                    p.positions_m.get(idx[2]),
                ) else {
                    continue;
                };
                out.triangles
                    .push([a.as_dvec3(), b.as_dvec3(), c.as_dvec3()]);
                out.colours.push(idx.map(corner));
            }
        }
        let n = (out.colours.len() * 3) as f64;
        if n == 0.0 {
            return None;
        }
        let varies = (0..3).any(|ch| {
            let values = out.colours.iter().flatten().map(|c| f64::from(c[ch]));
            let (s, s2) = values.fold((0.0, 0.0), |(s, s2), v| (s + v, s2 + v * v));
            let var = s2 / n - (s / n).powi(2);
            var.max(0.0).sqrt() >= 0.02
        });
        varies.then_some(out)
    }

    /// The model's edges inside its outline at `pose` over `rect` (rasterized at most
    /// `raster_px` across): where its own colours change (a grey-level gradient of at least
    /// `min_gradient`, thinned to its maxima) or one part of it hides another (a step in
    /// depth of over 2 % of the distance), as points in the object frame with a second point
    /// one pixel along the edge, like a [`crate::edge_refine::Contour`]'s; at most
    /// `max_points`, spread evenly.
    pub fn interior_edges(
        &self,
        pose: &Pose,
        k: &Intrinsics,
        rect: Rect,
        raster_px: u32,
        min_gradient: f32,
        max_points: usize,
    ) -> Vec<[DVec3; 2]> {
        if max_points == 0 {
            return Vec::new();
        }
        let z = ZBuffer::new(&self.triangles, pose, k, rect, raster_px);
        self.interior_edges_of(&z, pose, k, min_gradient, max_points)
    }

    /// [`ColouredSurface::interior_edges`] from the surface already rasterized at `pose`.
    pub(crate) fn interior_edges_of(
        &self,
        z: &ZBuffer,
        pose: &Pose,
        k: &Intrinsics,
        min_gradient: f32,
        max_points: usize,
    ) -> Vec<[DVec3; 2]> {
        if max_points == 0 {
            return Vec::new();
        }
        let (w, h) = (z.w, z.h);
        let grey: Vec<f32> = (0..w * h)
            .map(|at| {
                self.colour_at(z, at).map_or(0.0, |c| {
                    255.0 * (0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2])
                })
            })
            .collect();
        let inside = |i: usize, j: usize| z.depth[j * w + i].is_finite();
        let mut gx = vec![0.0f32; w * h];
        let mut gy = vec![0.0f32; w * h];
        let mut interior = vec![false; w * h];
        for j in 1..h.saturating_sub(1) {
            for i in 1..w.saturating_sub(1) {
                // Two pixels in from the outline: the outline is the contour's.
                if (j.saturating_sub(2)..=(j + 2).min(h - 1))
                    .any(|jj| (i.saturating_sub(2)..=(i + 2).min(w - 1)).any(|ii| !inside(ii, jj)))
                {
                    continue;
                }
                interior[j * w + i] = true;
                let g = |di: isize, dj: isize| {
                    grey[(j as isize + dj) as usize * w + (i as isize + di) as usize]
                };
                (gx[j * w + i], gy[j * w + i]) = sobel(g);
            }
        }
        let mut found = Vec::new();
        for j in 1..h.saturating_sub(1) {
            for i in 1..w.saturating_sub(1) {
                let at = j * w + i;
                if !interior[at] {
                    continue;
                }
                let d = z.depth[at];
                // A step in depth to a farther neighbour: the normal points at it.
                let mut normal = DVec2::ZERO;
                for (di, dj) in [(1isize, 0isize), (-1, 0), (0, 1), (0, -1)] {
                    let n = z.depth[(j as isize + dj) as usize * w + (i as isize + di) as usize];
                    if n - d > 0.02 * d {
                        normal += DVec2::new(di as f64, dj as f64);
                    }
                }
                if normal.length_squared() < 1e-9 {
                    let (x, y) = (gx[at], gy[at]);
                    let m = x.hypot(y);
                    if m < min_gradient {
                        continue;
                    }
                    // Thinned: a maximum along its gradient (4 directions).
                    let a = f64::from(y)
                        .atan2(f64::from(x))
                        .rem_euclid(std::f64::consts::PI);
                    let q = ((a / std::f64::consts::FRAC_PI_4).round() as usize) % 4;
                    let (di, dj): (isize, isize) = [(1, 0), (1, 1), (0, 1), (-1, 1)][q];
                    let mag = |ii: isize, jj: isize| {
                        let at = (j as isize + jj) as usize * w + (i as isize + ii) as usize;
                        gx[at].hypot(gy[at])
                    };
                    if m < mag(di, dj) || m < mag(-di, -dj) {
                        continue;
                    }
                    normal = DVec2::new(f64::from(x), f64::from(y));
                }
                let n = normal.normalize();
                let tangent = DVec2::new(-n.y, n.x);
                let at_img = z.to_image(DVec2::new(i as f64 + 0.5, j as f64 + 0.5));
                let dd = f64::from(d);
                found.push([
                    to_object(k, pose, at_img, dd),
                    to_object(k, pose, at_img + tangent, dd),
                ]);
            }
        }
        let n = max_points;
        if found.len() <= n {
            found
        } else {
            (0..n).map(|i| found[i * found.len() / n]).collect()
        }
    }

    /// Up to `max_points` points of the surface seen in `z` (rasterized at `pose`), spread
    /// evenly over its pixels, each in the object frame with its colour there (0..255): what
    /// [`photometric_cost`] compares with the image as the pose moves.
    pub(crate) fn samples_of(
        &self,
        z: &ZBuffer,
        pose: &Pose,
        k: &Intrinsics,
        max_points: usize,
    ) -> Vec<(DVec3, [f32; 3])> {
        let covered: Vec<usize> = (0..z.w * z.h)
            .filter(|&at| z.depth[at].is_finite())
            .collect();
        if max_points == 0 || covered.is_empty() {
            return Vec::new();
        }
        let n = max_points.min(covered.len());
        (0..n)
            .filter_map(|i| {
                let at = covered[i * covered.len() / n];
                let colour = self.colour_at(z, at)?.map(|v| 255.0 * v);
                let p = z.to_image(DVec2::new((at % z.w) as f64 + 0.5, (at / z.w) as f64 + 0.5));
                Some((to_object(k, pose, p, f64::from(z.depth[at])), colour))
            })
            .collect()
    }

    /// The model's colour (0..1) at raster pixel `at` of `z` (these triangles rasterized),
    /// interpolated between its triangle's corners; None where no surface is seen.
    pub(crate) fn colour_at(&self, z: &ZBuffer, at: usize) -> Option<[f32; 3]> {
        if !z.depth[at].is_finite() {
            return None;
        }
        let (tri, [b0, b1]) = z.hit[at];
        let c = self.colours.get(tri as usize)?;
        let b2 = 1.0 - b0 - b1;
        Some([0, 1, 2].map(|ch| b0 * c[0][ch] + b1 * c[1][ch] + b2 * c[2][ch]))
    }
}

/// How far the image's colours under `samples` (from [`ColouredSurface::samples_of`]) at
/// `pose` are from the samples' own: 1 minus their normalized cross-correlation ([`ncc`]),
/// 0..2, 0 where they agree up to a gain and an offset. Samples projecting outside `colours`'
/// region do not count; None with too few left or a flat side.
pub(crate) fn photometric_cost(
    samples: &[(DVec3, [f32; 3])],
    colours: &RegionColours,
    pose: &Pose,
    k: &Intrinsics,
) -> Option<f64> {
    let pairs: Vec<([f64; 3], [f64; 3])> = samples
        .iter()
        .filter_map(|(p, c)| {
            let at = project(k, pose.rotation * *p + pose.translation_m)?;
            let px = colours.at(at.x, at.y)?;
            Some((c.map(f64::from), px.map(f64::from)))
        })
        .collect();
    ncc(&pairs).map(|v| 1.0 - v)
}

/// An RGB8 image (`width × height × 3` bytes, row-major) and the coloured model to compare
/// with it.
#[derive(Debug, Clone, Copy)]
pub struct Appearance<'a> {
    pub rgb: &'a [u8],
    pub width: u32,
    pub height: u32,
    pub surface: &'a ColouredSurface,
}

impl Appearance<'_> {
    /// How well the model's colours at `pose` agree with the image over `rect` (rasterized at
    /// most `raster_px` across): the normalized cross-correlation of rendered and image
    /// colours over the pixels the model covers (each channel's mean removed, the channels
    /// pooled), in [-1, 1]; invariant to the image's gain and offset, so to the lighting's
    /// strength. None when the model covers fewer than 30 pixels of the image or either side
    /// is flat there.
    pub fn agreement(
        &self,
        pose: &Pose,
        k: &Intrinsics,
        rect: Rect,
        raster_px: u32,
    ) -> Option<f64> {
        let s = self.surface;
        let z = ZBuffer::new(&s.triangles, pose, k, rect, raster_px);
        let mut pairs: Vec<([f64; 3], [f64; 3])> = Vec::new();
        for j in 0..z.h {
            for i in 0..z.w {
                let at = j * z.w + i;
                if !z.depth[at].is_finite() {
                    continue;
                }
                let p = z.to_image(DVec2::new(i as f64 + 0.5, j as f64 + 0.5));
                let (x, y) = ((p.x + 0.5).floor(), (p.y + 0.5).floor());
                if x < 0.0 || y < 0.0 || x >= f64::from(self.width) || y >= f64::from(self.height) {
                    continue;
                }
                let Some(c) = s.colour_at(&z, at) else {
                    continue;
                };
                let rendered = c.map(|v| f64::from(v) * 255.0);
                let o = (y as usize * self.width as usize + x as usize) * 3;
                let Some(px) = self.rgb.get(o..o + 3) else {
                    continue;
                };
                pairs.push((rendered, [0, 1, 2].map(|ch| f64::from(px[ch]))));
            }
        }
        ncc(&pairs)
    }
}

/// Normalized cross-correlation of paired colours, each channel's mean removed and the
/// channels pooled; None below [`MIN_PIXELS`] pairs or with a flat side.
fn ncc(pairs: &[([f64; 3], [f64; 3])]) -> Option<f64> {
    if pairs.len() < MIN_PIXELS {
        return None;
    }
    let n = pairs.len() as f64;
    let mut mean_a = [0.0; 3];
    let mut mean_b = [0.0; 3];
    for (a, b) in pairs {
        for ch in 0..3 {
            mean_a[ch] += a[ch] / n;
            mean_b[ch] += b[ch] / n;
        }
    }
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (a, b) in pairs {
        for ch in 0..3 {
            let (da, db) = (a[ch] - mean_a[ch], b[ch] - mean_b[ch]);
            ab += da * db;
            aa += da * da;
            bb += db * db;
        }
    }
    // Flat: under one grey level of standard deviation.
    (aa > n && bb > n).then(|| ab / (aa * bb).sqrt())
}

/// Test fixtures shared with [`crate::edge_refine`]'s tests: a two-coloured plate, a camera
/// and the plate's picture.
#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
pub(crate) mod fixtures {
    use super::*;
    use synthgen_core::glam::{DMat3, Vec3};
    use synthgen_core::{Material, Primitive};

    /// A square plate 10 cm across facing the camera (+z towards it), left half red, right
    /// half blue, by vertex colour.
    pub(crate) fn plate() -> Model {
        let positions_m = vec![
            Vec3::new(-0.05, -0.05, 0.0),
            Vec3::new(0.0, -0.05, 0.0),
            Vec3::new(0.0, 0.05, 0.0),
            Vec3::new(-0.05, 0.05, 0.0),
            Vec3::new(0.0, -0.05, 0.0),
            Vec3::new(0.05, -0.05, 0.0),
            Vec3::new(0.05, 0.05, 0.0),
            Vec3::new(0.0, 0.05, 0.0),
        ];
        let red = [0.9, 0.1, 0.1];
        let blue = [0.1, 0.1, 0.9];
        Model {
            name: "plate".into(),
            source: "plate.ply".into(),
            primitives: vec![Primitive {
                positions_m,
                normals: None,
                colors: Some(vec![red, red, red, red, blue, blue, blue, blue]),
                uvs: None,
                triangles: vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]],
                material: Material {
                    base_color: [1.0; 3],
                    double_sided: true,
                    ..Material::default()
                },
            }],
        }
    }

    pub(crate) fn camera() -> Intrinsics {
        Intrinsics {
            width: 160,
            height: 120,
            fx: 500.0,
            fy: 500.0,
            cx: 80.0,
            cy: 60.0,
        }
    }

    /// The plate half a metre in front of the camera, facing it.
    pub(crate) fn facing() -> Pose {
        Pose::new(DMat3::IDENTITY, DVec3::new(0.0, 0.0, 0.5))
    }

    /// The region around the plate's image.
    pub(crate) fn region() -> Rect {
        Rect::square_in(80.0, 60.0, 110.0, 160, 120).unwrap()
    }

    /// The image of the plate at `pose`: its colours where it is, grey elsewhere, everything
    /// at 60 % of the model's brightness plus 20 levels (other lighting).
    pub(crate) fn photo(surface: &ColouredSurface, pose: &Pose, k: &Intrinsics) -> Vec<u8> {
        let rect = Rect {
            x0: 0,
            y0: 0,
            w: k.width as i32,
            h: k.height as i32,
        };
        let z = ZBuffer::new(&surface.triangles, pose, k, rect, 1000);
        let mut img = vec![128u8; (k.width * k.height * 3) as usize];
        for at in 0..z.depth.len() {
            if let Some(c) = surface.colour_at(&z, at) {
                for ch in 0..3 {
                    img[at * 3 + ch] = (20.0 + 0.6 * 255.0 * c[ch]) as u8;
                }
            }
        }
        img
    }

    /// `img` (of `camera()`'s size) against `surface`.
    pub(crate) fn appearance<'a>(img: &'a [u8], surface: &'a ColouredSurface) -> Appearance<'a> {
        let k = camera();
        Appearance {
            rgb: img,
            width: k.width,
            height: k.height,
            surface,
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::fixtures::*;
    use super::*;
    use synthgen_core::glam::DMat3;

    #[test]
    fn the_true_side_agrees_and_the_turned_one_does_not() {
        let surface = ColouredSurface::from_model(&plate()).expect("two colours");
        let (k, pose) = (camera(), facing());
        let img = photo(&surface, &pose, &k);
        let a = appearance(&img, &surface);
        let right = a.agreement(&pose, &k, region(), 200).unwrap();
        // Turned by 180° about the view axis: the same outline, red and blue swapped.
        let turned = Pose::new(
            DMat3::from_rotation_z(std::f64::consts::PI),
            pose.translation_m,
        );
        let wrong = a.agreement(&turned, &k, region(), 200).unwrap();
        assert!(right > 0.99, "true pose agrees {right}");
        assert!(wrong < -0.9, "turned pose agrees {wrong}");
    }

    #[test]
    fn the_edges_inside_the_outline_follow_the_colour_change() {
        let surface = ColouredSurface::from_model(&plate()).unwrap();
        let (k, pose) = (camera(), facing());
        let points = surface.interior_edges(&pose, &k, region(), 200, 8.0, 40);
        assert!(points.len() >= 20, "{} points", points.len());
        for [p, q] in &points {
            // On the red/blue seam (x = 0) within two pixels (1 mm each at 0.5 m, f = 500),
            // the tangent along it.
            assert!(p.x.abs() < 0.002, "{p}");
            assert!((q - p).x.abs() < 0.1 * (q - p).length(), "{p} {q}");
        }
        assert!(surface
            .interior_edges(&pose, &k, region(), 200, 8.0, 0)
            .is_empty());
    }

    #[test]
    fn a_textured_model_takes_its_corner_colours_from_the_texture() {
        use std::sync::Arc;
        use synthgen_core::glam::Vec2;
        use synthgen_core::Texture;
        let mut m = plate();
        let p = &mut m.primitives[0];
        p.colors = None;
        // Two texels: red on the left (u < 0.5), blue on the right; the left half's corners
        // read the left texel, the right half's the right one.
        p.material.texture = Some(Arc::new(Texture {
            width: 2,
            height: 1,
            rgb: vec![255, 0, 0, 0, 0, 255],
            source: "two.png".into(),
        }));
        p.uvs = Some(
            [0.1, 0.2, 0.3, 0.4, 0.6, 0.7, 0.8, 0.9]
                .map(|u| Vec2::new(u, 0.5))
                .to_vec(),
        );
        p.material.base_color = [0.5, 1.0, 1.0];
        let s = ColouredSurface::from_model(&m).expect("two texels");
        assert_eq!(s.colours[0], [[0.5, 0.0, 0.0]; 3]);
        assert_eq!(s.colours[2], [[0.0, 0.0, 1.0]; 3]);
        // The same picture as the vertex-coloured plate's, so the same verdicts.
        let (k, pose) = (camera(), facing());
        let img = photo(&s, &pose, &k);
        let a = appearance(&img, &s);
        assert!(a.agreement(&pose, &k, region(), 200).unwrap() > 0.99);
    }

    #[test]
    fn a_flat_coloured_model_says_nothing() {
        let mut m = plate();
        m.primitives[0].colors = None;
        assert!(ColouredSurface::from_model(&m).is_none());
    }

    #[test]
    fn a_flat_image_says_nothing() {
        let surface = ColouredSurface::from_model(&plate()).unwrap();
        let k = camera();
        let img = vec![0u8; (k.width * k.height * 3) as usize];
        let a = appearance(&img, &surface);
        assert_eq!(a.agreement(&facing(), &k, region(), 200), None);
    }

    #[test]
    fn a_model_off_the_image_says_nothing() {
        let surface = ColouredSurface::from_model(&plate()).unwrap();
        let k = camera();
        let img = photo(&surface, &facing(), &k);
        let a = appearance(&img, &surface);
        let away = Pose::new(DMat3::IDENTITY, DVec3::new(2.0, 0.0, 0.5));
        assert_eq!(a.agreement(&away, &k, region(), 200), None);
    }
}
