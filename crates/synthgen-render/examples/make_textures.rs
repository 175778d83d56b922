//! Writes the procedural textures of `synthgen_render::procedural` as PNGs:
//! `cargo run -p synthgen-render --example make_textures -- textures` (the repo's folder).

use std::path::PathBuf;

use anyhow::{Context, Result};
use synthgen_render::procedural::{texture, TEXTURES};

fn main() -> Result<()> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .context("usage: make_textures OUT_DIR")?,
    );
    for (folder, name) in TEXTURES {
        let tex = texture(name).context("unknown texture")?;
        let dir = out.join(folder);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let path = dir.join(format!("{name}.png"));
        image::RgbImage::from_raw(tex.width, tex.height, tex.rgb)
            .context("texture size")?
            .save(&path)
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("{}", path.display());
    }
    Ok(())
}
