//! Arguments of `synthgen model align`.

use std::path::PathBuf;

use clap::{Args, Subcommand};

#[derive(Debug, Subcommand)]
pub enum ModelCommand {
    /// Put a (textured) scan into the frame of the model a dataset's poses refer to: coarse
    /// alignment, then ICP; refuses surfaces that do not match.
    #[command(after_long_help = ALIGN_EXAMPLES)]
    Align(ModelAlignArgs),
}

pub const ALIGN_EXAMPLES: &str = "Examples:
  # The YCB google_16k scan of the cracker box onto the YCB-Video model its poses refer to:
  synthgen model align --scan ../shared/data/ycb_textured/003_cracker_box/textured.obj \\
      --to ../shared/data/ycbv_real/models/003_cracker_box/textured_simple.obj \\
      --out models_tex/003_cracker_box

  # Every scan of a folder onto a dataset's models (one subfolder per class), then a
  # textured replay of the real frames:
  synthgen model align --scans ../shared/data/ycb_textured \\
      --to-dataset ../shared/data/ycbv_real --out models_tex
  synthgen render --replay ../shared/data/ycbv_real --replay-models models_tex \\
      --format ycbv --out out/ycbv_tex

  # Files whose axes differ: also try the 24 axis-aligned rotations:
  synthgen model align --scan scan.obj --to obj_000005.ply --rotation-search --out aligned/

Both meshes are read with their units decided per file, as `render --units auto` does (a
bounding-box diagonal over 5 units is millimetres); the moved scan keeps its own units. The scan's
surface is sampled by area; its centroid is put on the model's (with --rotation-search under
each axis-aligned rotation), then trimmed point-to-surface ICP (parry's BVH, Horn's method)
runs until the motion is under a micrometre. The residual is measured both ways (scan points
to the model surface, model points to the scan surface); over --max-median-mm the surfaces
are different shapes and nothing is written (exit 1).

Writes OUT/<the scan's file name> (positions and normals moved, UVs, faces and materials as
they were), its .mtl and the textures it names, and OUT/align.json (the motion, the
residuals). Only OBJ scans are written; any supported format can be --to. With --scans, a
table of every object; the exit status is 1 when any scan was refused (the others are
written).";

#[derive(Debug, Args)]
pub struct ModelAlignArgs {
    /// The scan to move (OBJ with its .mtl and textures).
    #[arg(
        long,
        value_name = "FILE",
        requires = "to",
        required_unless_present = "scans"
    )]
    pub scan: Option<PathBuf>,

    /// The model the annotations refer to (.ply, .obj, .gltf, .glb).
    #[arg(long, value_name = "FILE", requires = "scan")]
    pub to: Option<PathBuf>,

    /// A folder of scans, one subfolder per object named as --to-dataset names it (YCB-Video's
    /// class, `003_cracker_box`; BOP's `obj_000005`) with one OBJ in it: each is aligned to
    /// that dataset's model into OUT/<name>/, a folder `render --replay-models` takes.
    #[arg(long, value_name = "DIR", requires = "to_dataset", conflicts_with_all = ["scan", "to"])]
    pub scans: Option<PathBuf>,

    /// The dataset (BOP, Linemod or YCB-Video) whose models the --scans are aligned to.
    #[arg(long, value_name = "DIR", requires = "scans")]
    pub to_dataset: Option<PathBuf>,

    /// Output folder for the moved scan, its materials and textures, and align.json (with
    /// --scans: one such folder per object).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Replace the files of an earlier alignment in --out.
    #[arg(long)]
    pub force: bool,

    /// Also try the 24 axis-aligned rotations as starting points (files whose axes differ).
    #[arg(long)]
    pub rotation_search: bool,

    /// The largest median surface distance (the larger of the two directions) accepted as
    /// the same shape, millimetres.
    #[arg(long, value_name = "MM", default_value_t = 2.0)]
    pub max_median_mm: f64,

    /// Surface points per mesh.
    #[arg(long, default_value_t = 4000)]
    pub samples: usize,

    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}
