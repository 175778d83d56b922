//! Reads the multilayer EXR Blender writes for a frame: `ViewLayer.Combined.{R,G,B,A}`,
//! `ViewLayer.Depth.Z`, `ViewLayer.IndexOB.X` (rows top to bottom, as EXR stores them).

use std::path::Path;

use exr::prelude::{read_all_flat_layers_from_file, FlatSamples};

use crate::Error;

/// The passes of one frame, row-major from the top-left pixel.
pub struct Passes {
    pub width: u32,
    pub height: u32,
    /// Linear, premultiplied RGBA.
    pub rgba: Vec<f32>,
    pub z: Vec<f32>,
    pub index: Vec<f32>,
}

pub fn read_passes(path: &Path) -> Result<Passes, Error> {
    let err = |reason: String| Error::Passes {
        reason,
        path: path.to_path_buf(),
    };
    let image = read_all_flat_layers_from_file(path).map_err(|e| err(e.to_string()))?;
    let (mut w, mut h) = (0u32, 0u32);
    let mut channels: Vec<(String, Vec<f32>)> = Vec::new();
    for layer in &image.layer_data {
        let prefix = layer
            .attributes
            .layer_name
            .as_ref()
            .map(|n| format!("{n}."))
            .unwrap_or_default();
        (w, h) = (layer.size.0 as u32, layer.size.1 as u32);
        for ch in &layer.channel_data.list {
            let values = match &ch.sample_data {
                FlatSamples::F32(v) => v.clone(),
                FlatSamples::F16(v) => v.iter().map(|x| x.to_f32()).collect(),
                FlatSamples::U32(v) => v.iter().map(|&x| x as f32).collect(),
            };
            channels.push((format!("{prefix}{}", ch.name), values));
        }
    }
    let find = |suffixes: &[&str]| -> Result<Vec<f32>, Error> {
        channels
            .iter()
            .find(|(n, _)| suffixes.iter().any(|s| n.ends_with(s)))
            .map(|(_, v)| v.clone())
            .ok_or_else(|| {
                err(format!(
                    "no channel {} among {}",
                    suffixes.join(" or "),
                    channels
                        .iter()
                        .map(|c| c.0.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            })
    };
    let n = w as usize * h as usize;
    let rgba_ch = [
        find(&["Combined.R"])?,
        find(&["Combined.G"])?,
        find(&["Combined.B"])?,
        find(&["Combined.A"])?,
    ];
    let z = find(&["Depth.Z"])?;
    let index = find(&["IndexOB.X", "Object Index.X"])?;
    if rgba_ch.iter().any(|c| c.len() != n) || z.len() != n || index.len() != n {
        return Err(err(format!("channels do not hold {w}x{h} values")));
    }
    let mut rgba = Vec::with_capacity(n * 4);
    for i in 0..n {
        rgba.extend(rgba_ch.iter().map(|c| c[i]));
    }
    Ok(Passes {
        width: w,
        height: h,
        rgba,
        z,
        index,
    })
}
