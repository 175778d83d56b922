//! PLY reading (ascii and binary_little_endian), our own parser: the format is small and the
//! BOP models must load fast.
//!
//! Read: `vertex` x, y, z (any type), optional nx, ny, nz, red, green, blue (integer types are
//! scaled to 0..1 by their maximum, floats taken as they are; alpha is ignored), texture
//! coordinates as texture_u/texture_v, s/t or u/v; `face` with a `vertex_indices` or
//! `vertex_index` list, polygons triangulated as fans. Other elements and properties are
//! skipped. `comment TextureFile NAME` loads that texture (relative to the file) when the
//! vertices have texture coordinates.

mod body;
mod header;

use std::path::Path;

use synthgen_core::glam::{Vec2, Vec3};
use synthgen_core::{Material, Model, Primitive, Progress};

use crate::texture::TextureCache;
use crate::Error;
use body::{Ascii, Binary, Body, Fail};
use header::{Element, Format, Header, Kind};

/// Loads a PLY file in its raw units.
pub(crate) fn load_ply(
    path: &Path,
    textures: &mut TextureCache,
    progress: &dyn Progress,
) -> Result<Model, Error> {
    let bytes = crate::read_file(path)?;
    let mut prim = parse_ply(&bytes, path, progress)?;
    // A texture without texture coordinates could not be mapped: ignore it.
    let texture_file = prim.texture_file.take().filter(|_| prim.prim.uvs.is_some());
    if let Some(name) = texture_file {
        let tex_path = crate::model_dir(path).join(name);
        let fallback = if prim.prim.colors.is_some() {
            "the vertex colours"
        } else {
            "the default colour"
        };
        prim.prim.material.texture = textures.load(&tex_path, fallback, progress);
        if prim.prim.material.texture.is_some() {
            prim.prim.material.base_color = [1.0; 3];
        }
    }
    Ok(Model {
        name: crate::file_stem(path),
        source: path.to_path_buf(),
        primitives: vec![prim.prim],
    })
}

pub(crate) struct ParsedPly {
    pub prim: Primitive,
    pub texture_file: Option<String>,
}

// Slots of one vertex's values.
const X: usize = 0;
const NX: usize = 3;
const R: usize = 6;
const U: usize = 9;
const SLOTS: usize = 11;

/// Parses PLY bytes into one primitive (raw units, not yet validated as a whole).
pub(crate) fn parse_ply(
    bytes: &[u8],
    path: &Path,
    progress: &dyn Progress,
) -> Result<ParsedPly, Error> {
    let header = header::parse_header(bytes, path)?;
    let body = &bytes[header.body_start..];
    let mut out = match header.format {
        Format::Ascii => {
            // Borrowed (no copy) for valid text; invalid bytes become U+FFFD and then fail
            // to parse, reported with the element and line that hold them.
            let text = String::from_utf8_lossy(body);
            read_body(
                &mut Ascii::new(&text, header.lines + 1),
                &header,
                body.len(),
                path,
            )?
        }
        Format::BinaryLittleEndian => read_body(&mut Binary::new(body), &header, body.len(), path)?,
    };
    if out.short_faces > 0 {
        progress.warn(&format!(
            "skipped {} faces with fewer than 3 vertices: {}",
            out.short_faces,
            path.display()
        ));
    }
    if out.prim.colors.is_some() {
        // Vertex colours carry the appearance; the base colour only multiplies them.
        out.prim.material.base_color = [1.0; 3];
    }
    Ok(ParsedPly {
        prim: out.prim,
        texture_file: header.texture_file,
    })
}

struct Out {
    prim: Primitive,
    short_faces: usize,
}

/// Where each vertex property goes: slot and scale.
fn vertex_slots(el: &Element) -> Vec<Option<(usize, f64)>> {
    el.props
        .iter()
        .map(|p| {
            let Kind::Scalar(ty) = p.kind else {
                return None;
            };
            let slot = match p.name.as_str() {
                "x" => X,
                "y" => X + 1,
                "z" => X + 2,
                "nx" => NX,
                "ny" => NX + 1,
                "nz" => NX + 2,
                "red" | "diffuse_red" | "r" => R,
                "green" | "diffuse_green" | "g" => R + 1,
                "blue" | "diffuse_blue" | "b" => R + 2,
                "texture_u" | "s" | "u" => U,
                "texture_v" | "t" | "v" => U + 1,
                _ => return None,
            };
            let scale = if (R..R + 3).contains(&slot) && !ty.is_float() {
                1.0 / ty.int_range().1 as f64
            } else {
                1.0
            };
            Some((slot, scale))
        })
        .collect()
}

fn has_all(slots: &[Option<(usize, f64)>], first: usize, n: usize) -> bool {
    (first..first + n).all(|s| slots.iter().any(|x| x.is_some_and(|(t, _)| t == s)))
}

fn read_body<B: Body>(b: &mut B, h: &Header, body_len: usize, path: &Path) -> Result<Out, Error> {
    let Some(vertex_el) = h.elements.iter().find(|e| e.name == "vertex") else {
        return Err(Error::PlyHeader {
            line: h.lines,
            reason: "no vertex element".into(),
            path: path.to_path_buf(),
        });
    };
    let slots = vertex_slots(vertex_el);
    if !has_all(&slots, X, 3) {
        return Err(Error::PlyHeader {
            line: h.lines,
            reason: "vertex element lacks x, y or z".into(),
            path: path.to_path_buf(),
        });
    }
    let (want_n, want_c, want_uv) = (
        has_all(&slots, NX, 3),
        has_all(&slots, R, 3),
        has_all(&slots, U, 2),
    );
    let face_el = h.elements.iter().find(|e| e.name == "face");
    let face_prop = match face_el {
        Some(el) if el.count > 0 => {
            match el
                .prop("vertex_indices")
                .or_else(|| el.prop("vertex_index"))
            {
                Some(p) if matches!(p.kind, Kind::List { .. }) => p.name.clone(),
                _ => {
                    return Err(Error::PlyHeader {
                        line: h.lines,
                        reason: "face element has no vertex_indices list".into(),
                        path: path.to_path_buf(),
                    })
                }
            }
        }
        _ => {
            return Err(Error::NoFaces {
                path: path.to_path_buf(),
            })
        }
    };

    let nv = vertex_el.count;
    // Capacity bounded by the body size so a lying header cannot exhaust memory.
    let cap = |n: usize| n.min(body_len);
    let mut positions = Vec::with_capacity(cap(nv));
    let mut normals = Vec::with_capacity(if want_n { cap(nv) } else { 0 });
    let mut colors = Vec::with_capacity(if want_c { cap(nv) } else { 0 });
    let mut uvs = Vec::with_capacity(if want_uv { cap(nv) } else { 0 });
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut short_faces = 0usize;
    let mut poly: Vec<u32> = Vec::with_capacity(8);

    let fail = |f: Fail, el: &Element, index: usize, line: Option<usize>| match f {
        Fail::Truncated => Error::PlyTruncated {
            element: el.name.clone(),
            index,
            count: el.count,
            path: path.to_path_buf(),
        },
        Fail::Bad(reason) => Error::PlyBody {
            element: el.name.clone(),
            index,
            line,
            reason,
            path: path.to_path_buf(),
        },
        Fail::IndexOutOfRange(i) => Error::IndexOutOfRange {
            face: index,
            index: i,
            vertex_count: nv,
            path: path.to_path_buf(),
        },
        Fail::NonFinite => Error::NonFiniteVertex {
            vertex: index,
            path: path.to_path_buf(),
        },
    };

    for el in &h.elements {
        let is_vertex = std::ptr::eq(el, vertex_el);
        let is_face = face_el.is_some_and(|f| std::ptr::eq(el, f));
        if is_vertex {
            for i in 0..el.count {
                let mut v = [0f64; SLOTS];
                read_vertex(b, el, &slots, &mut v).map_err(|f| fail(f, el, i, b.line()))?;
                let p = Vec3::new(v[X] as f32, v[X + 1] as f32, v[X + 2] as f32);
                if !p.is_finite() {
                    return Err(fail(Fail::NonFinite, el, i, b.line()));
                }
                positions.push(p);
                if want_n {
                    normals.push(Vec3::new(v[NX] as f32, v[NX + 1] as f32, v[NX + 2] as f32));
                }
                if want_c {
                    colors.push([v[R] as f32, v[R + 1] as f32, v[R + 2] as f32]);
                }
                if want_uv {
                    // PLY texture coordinates follow OpenGL (v = 0 at the bottom row).
                    uvs.push(Vec2::new(v[U] as f32, 1.0 - v[U + 1] as f32));
                }
            }
        } else if is_face {
            triangles.reserve(cap(el.count));
            for i in 0..el.count {
                poly.clear();
                read_face(b, el, &face_prop, nv, &mut poly)
                    .map_err(|f| fail(f, el, i, b.line()))?;
                if poly.len() < 3 {
                    short_faces += 1;
                    continue;
                }
                for k in 1..poly.len() - 1 {
                    triangles.push([poly[0], poly[k], poly[k + 1]]);
                }
            }
        } else {
            b.skip(el).map_err(|(i, f)| fail(f, el, i, b.line()))?;
        }
    }
    if triangles.is_empty() {
        return Err(Error::NoFaces {
            path: path.to_path_buf(),
        });
    }
    Ok(Out {
        prim: Primitive {
            positions_m: positions,
            normals: want_n.then_some(normals),
            colors: want_c.then_some(colors),
            uvs: want_uv.then_some(uvs),
            triangles,
            material: Material::default(),
        },
        short_faces,
    })
}

#[inline]
fn read_vertex<B: Body>(
    b: &mut B,
    el: &Element,
    slots: &[Option<(usize, f64)>],
    v: &mut [f64; SLOTS],
) -> Result<(), Fail> {
    b.begin()?;
    for (p, slot) in el.props.iter().zip(slots) {
        match p.kind {
            Kind::Scalar(t) => {
                let x = b.scalar(t, &p.name)?;
                if let Some((s, scale)) = *slot {
                    v[s] = x * scale;
                }
            }
            Kind::List { count, item } => {
                for _ in 0..b.count(count, &p.name)? {
                    b.scalar(item, &p.name)?;
                }
            }
        }
    }
    b.end()
}

#[inline]
fn read_face<B: Body>(
    b: &mut B,
    el: &Element,
    indices_prop: &str,
    nv: usize,
    poly: &mut Vec<u32>,
) -> Result<(), Fail> {
    b.begin()?;
    for p in &el.props {
        match p.kind {
            Kind::Scalar(t) => {
                b.scalar(t, &p.name)?;
            }
            Kind::List { count, item } => {
                let n = b.count(count, &p.name)?;
                let is_indices = p.name == indices_prop;
                for _ in 0..n {
                    let x = b.scalar(item, &p.name)?;
                    if is_indices {
                        if item.is_float() && x.fract() != 0.0 {
                            return Err(Fail::Bad(format!("non-integer vertex index {x}")));
                        }
                        if x < 0.0 || x >= nv as f64 {
                            return Err(Fail::IndexOutOfRange(x as i64));
                        }
                        poly.push(x as u32);
                    }
                }
            }
        }
    }
    b.end()
}
