//! Which layout a dataset folder has, and a [`FrameSource`] over it whatever it is: the one
//! place that knows every layout, above the layouts themselves (`bop`, `linemod`, `ycbv`, which
//! each implement [`FrameSource`]) and below what reads any of them (`validate`, `convert`, and
//! the crates that mix, fit and train).

use std::path::Path;

use serde::Serialize;

use crate::bop::BopDataset;
use crate::error::{Error, Result};
use crate::linemod::source::LinemodSource;
use crate::source::FrameSource;
use crate::ycbv::YcbvSource;

/// The dataset layouts synthgen reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    Bop,
    Linemod,
    Ycbv,
}

impl Layout {
    /// The layout's name in commands and files (`bop`, `linemod`, `ycbv`).
    pub fn name(self) -> &'static str {
        match self {
            Layout::Bop => "bop",
            Layout::Linemod => "linemod",
            Layout::Ycbv => "ycbv",
        }
    }
}

impl std::fmt::Display for Layout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Layout::Bop => "BOP",
            Layout::Linemod => "Linemod",
            Layout::Ycbv => "YCB-Video",
        })
    }
}

/// `camera.json` → BOP; `classes.txt` beside `data/` → YCB-Video; `data/NN/gt.yml` →
/// Linemod; else `None`.
pub fn detect_layout(root: &Path) -> Option<Layout> {
    if root.join("camera.json").is_file() {
        return Some(Layout::Bop);
    }
    if crate::ycbv::is_ycbv(root) {
        return Some(Layout::Ycbv);
    }
    let entries = std::fs::read_dir(root.join("data")).ok()?;
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.bytes().all(|b| b.is_ascii_digit()) && e.path().join("gt.yml").is_file() {
            return Some(Layout::Linemod);
        }
    }
    None
}

/// Opens a dataset folder in whichever layout it has (see [`detect_layout`]): Linemod,
/// YCB-Video, else BOP (whose errors then name what is missing).
pub fn open_source(root: &Path) -> Result<Box<dyn FrameSource>> {
    if !root.is_dir() {
        return Err(Error::NoSuchDataset {
            path: root.to_path_buf(),
        });
    }
    match detect_layout(root) {
        Some(Layout::Linemod) => Ok(Box::new(LinemodSource::open(root)?)),
        Some(Layout::Ycbv) => Ok(Box::new(YcbvSource::open(root)?)),
        _ => Ok(Box::new(BopDataset::open(root)?)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detects_nothing_in_an_empty_folder() {
        let d = tempfile::tempdir().unwrap();
        assert_eq!(detect_layout(d.path()), None);
        std::fs::create_dir_all(d.path().join("data/01")).unwrap();
        std::fs::write(d.path().join("data/01/gt.yml"), "").unwrap();
        assert_eq!(detect_layout(d.path()), Some(Layout::Linemod));
        std::fs::write(d.path().join("camera.json"), "{}").unwrap();
        assert_eq!(detect_layout(d.path()), Some(Layout::Bop));
    }
}
