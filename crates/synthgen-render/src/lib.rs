//! Renderers for synthgen: the `Renderer` trait and the embedded CPU rasterizer, producing
//! RGB, depth, instance ids and each object's depth rendered alone (for BOP annotations).
//!
//! ```
//! use synthgen_core::glam::{DMat3, DVec3, Vec3};
//! use synthgen_core::sample::ObjectInstance;
//! use synthgen_core::{FrameScene, Intrinsics, Model, Pose};
//! use synthgen_render::{CpuRenderer, Renderer};
//!
//! let renderer = CpuRenderer::new(vec![Model::cuboid("box", Vec3::splat(0.1))], vec![])?;
//! let box_at_half_a_metre = ObjectInstance {
//!     model_index: 0,
//!     obj_id: 1,
//!     cam_from_obj: Pose::new(DMat3::IDENTITY, DVec3::new(0.0, 0.0, 0.5)),
//!     brightness: 1.0,
//!     specular: 0.2,
//!     shininess: 32.0,
//!     tint: [1.0; 3],
//!     hue_deg: 0.0,
//!     metallic: 0.0,
//! };
//! // Only the box, flat-lit, on black: no lights, ground or walls.
//! let scene = FrameScene::bare(0, Intrinsics::LINEMOD, vec![box_at_half_a_metre]);
//! let frame = renderer.render(&scene)?;
//! let centre = 242 * 640 + 325;
//! assert_eq!(frame.instance[centre], 1);
//! assert!((frame.depth_m[centre] - 0.45).abs() < 1e-4); // the box's front face
//! let info = synthgen_core::annotate(&scene.intrinsics, &frame.depth_m, &frame.alone, 0.015);
//! assert_eq!(info[0].info.visib_fract, 1.0);
//! # Ok::<(), synthgen_render::Error>(())
//! ```
//!
//! # What the CPU renderer computes
//!
//! - **Coverage.** A pixel is covered by a triangle iff the pixel's centre lies inside it
//!   (pixel (x, y) has its centre at image coordinates (x, y), OpenCV convention). Centres
//!   exactly on an edge follow the top-left rule, so a pixel on an edge shared by two
//!   triangles belongs to exactly one. Vertices are snapped to 1/256 pixel and edge functions
//!   are exact integers. No antialiasing: every output is a single sample per pixel.
//! - **Depth** is z in the camera frame (along the optical axis, metres; not the distance
//!   along the ray), interpolated as 1/z, which is exact for planar triangles. 0 means
//!   nothing was hit.
//! - **Alone renders.** Each object is rasterized on its own into a window (the bounding box
//!   of its projected vertices, cut to the canvas three times the image size,
//!   `[-W, 2W) x [-H, 2H)`), with a z-buffer within the object. That buffer is
//!   `RenderedFrame::alone[i]`, and the frame is composited from the same buffers, so inside
//!   the image `alone[i]` is non-zero exactly where object i covers the pixel, and wherever
//!   object i is the nearest surface, `instance == i + 1` and `depth_m` equals its alone
//!   depth bit for bit. Ties between objects go to the lower index; a tie with the ground
//!   goes to the ground.
//! - **Near plane** (`CpuOptions::near_m`, default 1 cm): triangles crossing it are clipped
//!   in 3D (Sutherland-Hodgman) and the pieces rasterized; the same path clips against a
//!   guard band of 2^20 pixels so fixed-point products cannot overflow.
//! - **Culling.** Front faces are counter-clockwise seen from outside in the object's
//!   right-handed frame (OBJ/PLY/glTF), which reads clockwise in the y-down image. Back faces
//!   are culled unless the primitive's material is `double_sided`; double-sided faces are
//!   shaded with the normal flipped toward the camera. Runs of 16 neighbouring triangles
//!   whose normal cone faces away from the camera are skipped whole (a conservative test,
//!   so it never drops a front face).
//! - **Ground plane** (`FrameScene::ground`): its depth is the exact ray-plane intersection
//!   at each pixel centre inside the square, beyond the near plane; it occludes objects like
//!   any surface but has instance 0 and no alone render. Colour: the ground colour times a
//!   procedural tile texture (random 2 cm and 8 cm tiles, mean 1, contrast
//!   `texture_strength`, offset by `texture_seed`, repeating every 5.12 m), lit by ambient +
//!   Lambert (no specular); the irradiance is exact every 16 pixels along a row and linear in
//!   between (it varies by far less than a level over that distance).
//!   With `GroundInstance::texture` the tiles give way to an image (one of those given to
//!   `CpuRenderer::with_surface_textures`): linear-light mip chain, tiled every `scale_m`,
//!   nearest texel at the level matching the pixel's footprint depth / (fx |n·d|), times
//!   the ground colour.
//! - **Walls** (`FrameScene::walls`): rectangles drawn like the ground (exact ray-plane
//!   depth, instance 0, ties won against objects) after it, each pixel lit exactly and
//!   written only where the wall is nearest, so planes may be drawn in any order.
//! - **Shading** is deferred: only the pixel an object wins is shaded, with barycentrics
//!   recomputed exactly from the pixel-centre ray. Base colour = material `base_color` ×
//!   (texture, bilinear with wrap, if the primitive has uvs and a texture; else the
//!   per-vertex colour, stored as 8-bit sRGB, if present) × `ObjectInstance::brightness`.
//!   Light = `ambient` + Σ over point lights of `color × intensity × max(0, n·l)` (Lambert),
//!   plus highlights from the instance's per-frame `specular` and `shininess` (the material's
//!   own values are not used): Blinn-Phong `specular × color × intensity × (n·h)^shininess`
//!   (`Shading::Phong`), or a GGX lobe with Fresnel and `metallic` (`Shading::Ggx`, the
//!   scene spec's default; `shade.rs`). With `FrameScene::environment` the ambient comes
//!   from a sky and a ground colour, mixed by the normal's elevation. Lights have no distance falloff: `intensity` is the irradiance they deliver, so
//!   exposure does not depend on the sampled light distance. Normals are the interpolated
//!   vertex normals when the model has them, else the face normal. All maths in linear
//!   light; sRGB conversion in both directions goes through lookup tables.
//! - **Shadows** (`FrameScene::shadows`, `[lights] shadows`): after shading, one shadow map
//!   per light (`shadow.rs`: the casters rasterized from the light, 3x3 PCF); a pixel loses
//!   the Lambert share of each blocked light's contribution (normal from the depth buffer).
//! - **Ambient occlusion** (`FrameScene::ambient_occlusion`): screen-space obscurance from
//!   the depth buffer at a quarter of the pixels, filtered within a surface; a pixel loses
//!   that share of its ambient light (`ao.rs`). Shadows and occlusion are on in the scene
//!   spec's defaults; `FrameScene::bare` has neither.
//! - **Background** where nothing is hit: `Color`, `Noise` (uniform per-pixel RGB noise from
//!   the background seed) or `Images` (an image picked by the seed, cropped at a random
//!   50-100% scale and offset with the output's aspect ratio, maybe mirrored, nearest
//!   neighbour; an error when the renderer has no background images).
//! - **Determinism.** The same `FrameScene` gives byte-identical output on any thread and
//!   with any number of threads.
//!
//! # Speed
//!
//! Frames render in parallel across threads (`render_frames`); within a frame everything
//! runs on one thread, in passes written so that the compiler vectorizes them (no libm calls
//! or float-to-int casts in hot loops). Models are reordered once along a Morton curve so
//! that neighbouring pixels touch neighbouring memory. Triangles are classified branch-free
//! first (culled, empty, one candidate pixel, more), since scanned meshes project to mostly
//! sub-pixel triangles. Buffers live in a per-thread scratch reused from frame to frame;
//! `CpuRenderer::render_into` also reuses the output's buffers.
//!
//! The ground plane covers most of a typical frame (about 270k of the 307k pixels in the
//! `raster_rgbd_640x480` bench), so its row is drawn in few passes: one vectorized pass for
//! depth, depth test and tile index; a scalar pass for the tile-pattern lookups; then per
//! chunk of 16 pixels the sRGB table indices of the three channels (vectorized, kept in
//! registers) and the table lookups packed four pixels to three 32-bit stores. The sRGB table
//! is indexed by any u16, so lookups need neither mask nor bounds check.
//!
//! Where the time of one frame of that bench goes on one thread (5 Linemod models, about
//! 5.7 ms for render + annotate; milliseconds, from each phase's share of the instructions
//! scaled onto a measured frame): vertex transform 0.46, triangle culling and sorting 0.88,
//! 1-pixel triangles 0.71, multi-pixel triangles 0.74, composite 0.03, ground + background
//! 1.67, object shading 1.19, `synthgen_core::annotate` 0.31.

mod ao;
mod background;
mod bits;
mod color;
mod cpu;
mod error;
mod ground;
mod object_renderer;
mod prepare;
pub mod procedural;
mod raster;
pub mod sensor;
mod shade;
mod shadow;
mod surface;
mod view_check;

pub use cpu::{render_frames, CpuOptions, CpuRenderer};
pub use error::Error;
pub use object_renderer::ObjectRenderer;
pub use sensor::SensorModel;
pub use view_check::ViewChecker;

use synthgen_core::{FrameScene, RenderedFrame};

/// Something that turns a sampled frame into images.
pub trait Renderer {
    fn render(&self, scene: &FrameScene) -> Result<RenderedFrame, Error>;
    /// Short backend name for manifests and messages (`cpu`, `blender`).
    fn name(&self) -> &str;
}
