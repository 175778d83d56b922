//! COCO instance annotations from a BOP split, as bop_toolkit's `calc_gt_coco.py` writes
//! them (`scene_gt_coco.json` per scene folder): one image per frame, one annotation per
//! visible object instance with its `mask_visib` as RLE, `bbox` from `bbox_visib`, `area` =
//! visible pixels, `iscrowd` 0 and `ignore` for instances less visible than a threshold.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

use serde_json::{json, Value};

use crate::bop::{read_mask, BopDataset};
use crate::error::{Error, Result};
use crate::io::atomic_write;

/// File name bop_toolkit uses in each scene folder.
pub const SCENE_GT_COCO: &str = "scene_gt_coco.json";

/// RLE flavour of the `segmentation` field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RleFormat {
    /// `{"counts": [..], "size": [h, w]}` with integer run lengths (bop_toolkit's default).
    #[default]
    Uncompressed,
    /// pycocotools' compressed string counts (`mask.encode`).
    Compressed,
}

#[derive(Debug, Clone, PartialEq)]
pub struct CocoOptions {
    pub split: String,
    /// Instances with visib_fract below this get `"ignore": true`.
    pub ignore_below_visib_fract: f64,
    pub rle: RleFormat,
}

impl Default for CocoOptions {
    fn default() -> Self {
        CocoOptions {
            split: "train_pbr".into(),
            ignore_below_visib_fract: 0.1,
            rle: RleFormat::Uncompressed,
        }
    }
}

/// Run lengths of a mask in column-major (Fortran) order, starting with a run of zeros
/// (possibly empty), as pycocotools expects. `mask` is row-major, non-zero = set.
pub fn rle_counts(mask: &[u8], width: usize, height: usize) -> Vec<u32> {
    let mut counts = Vec::new();
    let mut current = false;
    let mut run = 0u32;
    for x in 0..width {
        for y in 0..height {
            let v = mask[y * width + x] != 0;
            if v != current {
                counts.push(run);
                run = 0;
                current = v;
            }
            run += 1;
        }
    }
    counts.push(run);
    counts
}

/// pycocotools' `rleToString`: deltas against the count two back (from the third on), 5
/// bits per char with a continuation bit, offset by 48.
pub fn rle_to_string(counts: &[u32]) -> String {
    let mut s = String::new();
    for (i, &c) in counts.iter().enumerate() {
        let mut x = i64::from(c);
        if i > 2 {
            x -= i64::from(counts[i - 2]);
        }
        loop {
            let mut ch = (x & 0x1f) as u8;
            x >>= 5;
            let more = if ch & 0x10 != 0 { x != -1 } else { x != 0 };
            if more {
                ch |= 0x20;
            }
            s.push(char::from(ch + 48));
            if !more {
                break;
            }
        }
    }
    s
}

/// Decodes uncompressed counts back to a row-major 0/1 mask (for tests and checks).
pub fn rle_decode(counts: &[u32], width: usize, height: usize) -> Vec<u8> {
    let mut col_major = Vec::with_capacity(width * height);
    for (i, &c) in counts.iter().enumerate() {
        col_major.extend(std::iter::repeat_n((i % 2) as u8, c as usize));
    }
    let mut out = vec![0u8; width * height];
    for (k, v) in col_major.into_iter().enumerate().take(width * height) {
        let (x, y) = (k / height, k % height);
        out[y * width + x] = v;
    }
    out
}

/// pycocotools' `rleFrString`, the inverse of [`rle_to_string`]; None when the string is
/// not one (a character outside `0`..`o`, a count cut short, a negative run).
pub fn rle_from_string(s: &str) -> Option<Vec<u32>> {
    let bytes = s.as_bytes();
    let mut counts: Vec<u32> = Vec::new();
    let mut p = 0;
    while p < bytes.len() {
        let mut x: i64 = 0;
        let mut k = 0;
        loop {
            let b = *bytes.get(p)?;
            if !(48..48 + 64).contains(&b) || k > 12 {
                return None;
            }
            let c = i64::from(b - 48);
            x |= (c & 0x1f) << (5 * k);
            p += 1;
            k += 1;
            if c & 0x20 == 0 {
                if c & 0x10 != 0 {
                    x |= -1i64 << (5 * k);
                }
                break;
            }
        }
        if counts.len() > 2 {
            x += i64::from(counts[counts.len() - 2]);
        }
        counts.push(u32::try_from(x).ok()?);
    }
    Some(counts)
}

/// A binary mask as COCO's run-length encoding: `size` is `[height, width]`, `counts` the
/// run lengths in column-major order starting with a run of zeros. Read from either COCO
/// form (`"counts"` a string, pycocotools' compressed one, or a list of integers); written
/// compressed, as `pycocotools.mask.encode` writes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rle {
    pub height: u32,
    pub width: u32,
    pub counts: Vec<u32>,
}

impl Rle {
    /// The RLE of a row-major mask (non-zero = set).
    pub fn from_mask(mask: &[u8], width: u32, height: u32) -> Rle {
        Rle {
            height,
            width,
            counts: rle_counts(mask, width as usize, height as usize),
        }
    }

    /// The RLE of a `width × height` mask that is zero outside the window `[x0, x0 + ww) ×
    /// [y0, y0 + wh)` and `window` (row-major, `ww × wh`, non-zero = set) inside it: the same
    /// counts as [`Rle::from_mask`] of the whole mask, in time of the window, not the frame.
    /// The window must lie inside the mask.
    pub fn from_window(window: &[u8], [x0, y0, ww, wh]: [u32; 4], width: u32, height: u32) -> Rle {
        debug_assert!(x0 + ww <= width && y0 + wh <= height);
        debug_assert_eq!(window.len(), (ww * wh) as usize);
        let h = u64::from(height);
        let mut counts: Vec<u32> = Vec::new();
        // The value of the open run, its length, and the column-major index after it.
        let (mut value, mut run, mut pos) = (0u8, 0u64, 0u64);
        let mut push = |v: u8, n: u64, value: &mut u8, run: &mut u64| {
            if n == 0 {
                return;
            }
            if v != *value {
                counts.push(*run as u32);
                *value = v;
                *run = 0;
            }
            *run += n;
        };
        for x in 0..ww {
            let col = u64::from(x0 + x) * h;
            for y in 0..wh {
                let idx = col + u64::from(y0 + y);
                push(0, idx - pos, &mut value, &mut run);
                let v = u8::from(window[(y * ww + x) as usize] != 0);
                push(v, 1, &mut value, &mut run);
                pos = idx + 1;
            }
        }
        push(0, h * u64::from(width) - pos, &mut value, &mut run);
        counts.push(run as u32);
        Rle {
            height,
            width,
            counts,
        }
    }

    /// The row-major 0/1 mask.
    pub fn decode(&self) -> Vec<u8> {
        rle_decode(&self.counts, self.width as usize, self.height as usize)
    }

    /// Set pixels.
    pub fn area(&self) -> u64 {
        self.counts
            .iter()
            .skip(1)
            .step_by(2)
            .map(|&c| u64::from(c))
            .sum()
    }

    /// Why the counts do not describe a `height` x `width` mask, if they do not.
    pub fn check(&self) -> std::result::Result<(), String> {
        let total: u64 = self.counts.iter().map(|&c| u64::from(c)).sum();
        let pixels = u64::from(self.height) * u64::from(self.width);
        if total != pixels {
            return Err(format!(
                "its runs cover {total} pixels, not the {} x {} = {pixels} of its size",
                self.height, self.width
            ));
        }
        Ok(())
    }

    /// pycocotools' `toBbox`: `[x, y, width, height]` of the set pixels (the last column
    /// `x + width - 1`), zeros when none is set.
    pub fn bbox(&self) -> [f64; 4] {
        let h = u64::from(self.height.max(1));
        let (mut xs, mut xe, mut ys, mut ye) = (u64::MAX, 0u64, u64::MAX, 0u64);
        let mut start = 0u64;
        for (j, &c) in self.counts.iter().enumerate() {
            let end = start + u64::from(c);
            if j % 2 == 1 && c > 0 {
                let (first, last) = (start, end - 1);
                let (x0, y0, x1, y1) = (first / h, first % h, last / h, last % h);
                xs = xs.min(x0);
                xe = xe.max(x1);
                if x1 > x0 {
                    ys = 0;
                    ye = h - 1;
                } else {
                    ys = ys.min(y0);
                    ye = ye.max(y1);
                }
            }
            start = end;
        }
        if xs == u64::MAX {
            return [0.0; 4];
        }
        [
            xs as f64,
            ys as f64,
            (xe - xs + 1) as f64,
            (ye - ys + 1) as f64,
        ]
    }

    /// Pixels set in both (same size assumed; the shorter run list ends the count).
    pub fn intersection(&self, other: &Rle) -> u64 {
        let (a, b) = (&self.counts, &other.counts);
        let (mut i, mut j) = (0, 0);
        let (mut ra, mut rb) = (
            a.first().copied().unwrap_or(0),
            b.first().copied().unwrap_or(0),
        );
        let mut total = 0u64;
        while i < a.len() && j < b.len() {
            let step = ra.min(rb);
            if i % 2 == 1 && j % 2 == 1 {
                total += u64::from(step);
            }
            ra -= step;
            rb -= step;
            while ra == 0 && i < a.len() {
                i += 1;
                ra = a.get(i).copied().unwrap_or(0);
            }
            while rb == 0 && j < b.len() {
                j += 1;
                rb = b.get(j).copied().unwrap_or(0);
            }
        }
        total
    }
}

impl serde::Serialize for Rle {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(2))?;
        m.serialize_entry("size", &[self.height, self.width])?;
        m.serialize_entry("counts", &rle_to_string(&self.counts))?;
        m.end()
    }
}

impl<'de> serde::Deserialize<'de> for Rle {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Rle, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Counts {
            Compressed(String),
            Runs(Vec<u32>),
        }
        #[derive(serde::Deserialize)]
        struct Raw {
            size: [u32; 2],
            counts: Counts,
        }
        let raw = Raw::deserialize(d)?;
        let counts = match raw.counts {
            Counts::Runs(c) => c,
            Counts::Compressed(s) => rle_from_string(&s).ok_or_else(|| {
                serde::de::Error::custom(format!(
                    "\"counts\" {:?} is not a COCO compressed RLE string",
                    s.chars().take(24).collect::<String>()
                ))
            })?,
        };
        let rle = Rle {
            height: raw.size[0],
            width: raw.size[1],
            counts,
        };
        rle.check().map_err(serde::de::Error::custom)?;
        Ok(rle)
    }
}

/// `rel` from `base` to `target` (both under one root), with `/` separators.
fn relative(target: &Path, base: &Path) -> String {
    let t: Vec<Component> = target.components().collect();
    let b: Vec<Component> = base.components().collect();
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = vec!["..".into(); b.len() - common];
    parts.extend(
        t[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

/// What [`export_coco`] wrote.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CocoSummary {
    pub files: Vec<PathBuf>,
    pub images: usize,
    pub annotations: usize,
    pub ignored: usize,
}

/// Writes COCO annotations for one split: per scene `scene_gt_coco.json` in the scene
/// folder, or, with `merged_out`, one file for the whole split (image and annotation ids
/// running over the scenes, file names relative to that file's folder).
pub fn export_coco(
    ds: &BopDataset,
    opts: &CocoOptions,
    merged_out: Option<&Path>,
    progress: &dyn synthgen_core::Progress,
) -> Result<CocoSummary> {
    if !ds.splits.contains(&opts.split) {
        return Err(Error::InvalidRequest(format!(
            "no split {:?} in {} (splits: {})",
            opts.split,
            ds.root.display(),
            ds.splits.join(", ")
        )));
    }
    let name = ds
        .root
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let categories: Vec<Value> = ds
        .models_info
        .iter()
        .flat_map(BTreeMap::keys)
        .map(|id| json!({"id": id, "name": id.to_string(), "supercategory": name}))
        .collect();
    let info = json!({
        "description": format!("{name}_{}", opts.split),
        "url": "https://github.com/thodan/bop_toolkit",
        "version": "0.1.0",
        "contributor": "synthgen",
    });
    let mut summary = CocoSummary::default();
    let scenes = ds
        .scene_ids(&opts.split)?
        .into_iter()
        .map(|id| ds.read_scene(&opts.split, id))
        .collect::<Result<Vec<_>>>()?;
    // Every annotation's category must be listed, or pycocotools breaks later: checked
    // before any file is written.
    let known = |id: u32| ds.models_info.as_ref().is_some_and(|m| m.contains_key(&id));
    for scene in &scenes {
        for (im_id, gts) in &scene.gt {
            if let Some((gt_id, gt)) = gts.iter().enumerate().find(|(_, g)| !known(g.obj_id)) {
                return Err(Error::malformed(
                    &scene.dir.join("scene_gt.json"),
                    format!(
                        "image {im_id}, gt {gt_id}: object {} is not in models/models_info.json, so COCO would have no category for it",
                        gt.obj_id
                    ),
                ));
            }
        }
    }
    progress.start("coco", scenes.len() as u64);
    let (mut images, mut annotations) = (Vec::new(), Vec::new());
    let (mut image_id, mut ann_id) = (0u64, 1u64);
    for scene in scenes {
        let base = match merged_out {
            Some(out) => out.parent().map(Path::to_path_buf).unwrap_or_default(),
            None => scene.dir.clone(),
        };
        if merged_out.is_none() {
            image_id = 0;
            ann_id = 1;
        }
        let info_path = scene.dir.join(crate::bop::SCENE_GT_INFO);
        for (&im_id, gts) in &scene.gt {
            let rgb = scene.rgb_path(im_id).ok_or_else(|| Error::MissingFile {
                path: scene.dir.join("rgb").join(format!("{im_id:06}.png")),
            })?;
            let (w, h) = (ds.camera.width, ds.camera.height);
            let file_name = if merged_out.is_some() {
                relative(&abs(rgb), &abs(&base))
            } else {
                relative(rgb, &base)
            };
            images.push(json!({
                "id": image_id, "file_name": file_name, "width": w, "height": h,
                "license": 1, "coco_url": "", "flickr_url": "",
            }));
            let infos = scene.gt_info.as_ref().and_then(|m| m.get(&im_id));
            for (gt_id, gt) in gts.iter().enumerate() {
                let this_id = ann_id;
                ann_id += 1;
                let mask_path = scene.mask_visib_path(im_id, gt_id);
                let mask = read_mask(&mask_path)?;
                if (mask.width, mask.height) != (w, h) {
                    return Err(Error::malformed(
                        &mask_path,
                        format!(
                            "mask is {}x{}, camera.json says {w}x{h}",
                            mask.width, mask.height
                        ),
                    ));
                }
                let area = mask.data.iter().filter(|&&v| v != 0).count();
                if area == 0 {
                    continue; // bop_toolkit skips instances without visible pixels
                }
                let info = infos.and_then(|i| i.get(gt_id)).ok_or_else(|| {
                    Error::malformed(
                        &info_path,
                        format!("no entry for image {im_id}, gt {gt_id} (COCO needs bbox_visib)"),
                    )
                })?;
                let counts = rle_counts(&mask.data, w as usize, h as usize);
                let counts = match opts.rle {
                    RleFormat::Uncompressed => json!(counts),
                    RleFormat::Compressed => json!(rle_to_string(&counts)),
                };
                let ignore = info.visib_fract < opts.ignore_below_visib_fract;
                summary.ignored += usize::from(ignore);
                annotations.push(json!({
                    "id": this_id, "image_id": image_id, "category_id": gt.obj_id,
                    "iscrowd": 0, "area": area, "bbox": info.bbox_visib,
                    "segmentation": {"counts": counts, "size": [h, w]},
                    "width": w, "height": h, "ignore": ignore,
                }));
            }
            image_id += 1;
        }
        if merged_out.is_none() {
            let path = scene.dir.join(SCENE_GT_COCO);
            summary.images += images.len();
            summary.annotations += annotations.len();
            write_coco(&path, &info, &categories, &mut images, &mut annotations)?;
            summary.files.push(path);
        }
        progress.advance(1);
    }
    if let Some(out) = merged_out {
        summary.images += images.len();
        summary.annotations += annotations.len();
        write_coco(out, &info, &categories, &mut images, &mut annotations)?;
        summary.files.push(out.to_path_buf());
    }
    progress.finish();
    Ok(summary)
}

fn abs(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

fn write_coco(
    path: &Path,
    info: &Value,
    categories: &[Value],
    images: &mut Vec<Value>,
    annotations: &mut Vec<Value>,
) -> Result<()> {
    let doc = json!({
        "info": info,
        "licenses": [],
        "categories": categories,
        "images": std::mem::take(images),
        "annotations": std::mem::take(annotations),
    });
    let text = serde_json::to_string(&doc).map_err(|e| Error::json(path, e))?;
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        crate::io::create_dir_all(parent)?;
    }
    atomic_write(path, text.as_bytes())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn rle_is_column_major_and_starts_with_zeros() {
        // 3 wide, 2 high:
        // 1 0 1
        // 1 0 0
        let m = [255, 0, 255, 255, 0, 0];
        let c = rle_counts(&m, 3, 2);
        assert_eq!(c, vec![0, 2, 2, 1, 1]);
        assert_eq!(rle_decode(&c, 3, 2), vec![1, 0, 1, 1, 0, 0]);
        assert_eq!(rle_counts(&[0; 4], 2, 2), vec![4]);
    }

    #[test]
    fn a_window_gives_the_counts_of_the_whole_mask() {
        // Deterministic pseudo-random windows and contents (an LCG), edges and corners too.
        let mut state = 12345u64;
        let mut next = |n: u32| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) % u64::from(n.max(1))) as u32
        };
        for case in 0..300 {
            let (w, h) = (1 + next(13), 1 + next(11));
            let (x0, y0) = (next(w), next(h));
            let (ww, wh) = (next(w - x0 + 1), next(h - y0 + 1));
            let window: Vec<u8> = (0..ww * wh)
                .map(|_| {
                    if case % 7 == 0 {
                        1
                    } else {
                        (next(3) == 0) as u8
                    }
                })
                .collect();
            let mut full = vec![0u8; (w * h) as usize];
            for y in 0..wh {
                for x in 0..ww {
                    full[((y0 + y) * w + x0 + x) as usize] = window[(y * ww + x) as usize];
                }
            }
            assert_eq!(
                Rle::from_window(&window, [x0, y0, ww, wh], w, h),
                Rle::from_mask(&full, w, h),
                "case {case}: {w}x{h}, window {x0},{y0} {ww}x{wh}"
            );
        }
    }

    #[test]
    fn compressed_rle_matches_pycocotools() {
        // Both checked against pycocotools 2.0 `mask.encode`: [[1,0,1],[1,0,0]] gives
        // b'022OO' (from the fourth run on, the delta to the count two back is coded:
        // 1 - 2 = -1 → 0x1f + 48 = 'O'), a 10x10 empty mask gives b'T3'.
        assert_eq!(rle_to_string(&[0, 2, 2, 1, 1]), "022OO");
        // A 100-long run needs two chars: 100 = 0b11_00100 → (4|0x20)+48, 3+48.
        assert_eq!(rle_to_string(&[100]), "T3");
    }

    #[test]
    fn compressed_rle_reads_back_and_describes_its_mask() {
        // A 4x3 mask (w 4, h 3) with an L and a lone pixel.
        #[rustfmt::skip]
        let m = [
            1, 0, 0, 0,
            1, 0, 0, 1,
            1, 1, 0, 0,
        ];
        let rle = Rle::from_mask(&m, 4, 3);
        assert_eq!(rle.area(), 5);
        assert_eq!(rle.bbox(), [0.0, 0.0, 4.0, 3.0]);
        assert_eq!(rle.decode(), m.to_vec());
        let text = serde_json::to_string(&rle).unwrap();
        let back: Rle = serde_json::from_str(&text).unwrap();
        assert_eq!(back, rle);
        // Runs of every size, including ones whose deltas are negative.
        for counts in [
            vec![0, 2, 2, 1, 1],
            vec![100],
            vec![5, 300, 2, 7000, 1, 1, 40000, 3, 0, 9],
        ] {
            assert_eq!(rle_from_string(&rle_to_string(&counts)), Some(counts));
        }
        // A box of one column and one row.
        let mut one = vec![0u8; 12];
        one[2 * 4 + 1] = 1;
        assert_eq!(Rle::from_mask(&one, 4, 3).bbox(), [1.0, 2.0, 1.0, 1.0]);
        assert_eq!(Rle::from_mask(&[0; 12], 4, 3).bbox(), [0.0; 4]);
        // The list form reads too; counts that miss the size or a bad string are errors.
        let list: Rle =
            serde_json::from_str(r#"{"size": [3, 4], "counts": [0, 3, 2, 1, 6]}"#).unwrap();
        assert_eq!(list.area(), 4);
        let e = serde_json::from_str::<Rle>(r#"{"size": [3, 4], "counts": [0, 3]}"#).unwrap_err();
        assert!(e.to_string().contains("cover 3 pixels"), "{e}");
        assert!(serde_json::from_str::<Rle>(r#"{"size": [3, 4], "counts": "~~~"}"#).is_err());
        assert_eq!(rle_from_string("22"), Some(vec![2, 2]));
        // A continuation with nothing after it; a negative run.
        assert_eq!(rle_from_string("o"), None);
        assert_eq!(rle_from_string("2O"), None);
    }

    #[test]
    fn intersections_count_shared_pixels() {
        let a = [1u8, 1, 0, 1, 1, 0, 0, 1, 1, 1, 0, 0];
        let b = [0u8, 1, 1, 1, 0, 0, 1, 1, 0, 1, 1, 0];
        let (ra, rb) = (Rle::from_mask(&a, 4, 3), Rle::from_mask(&b, 4, 3));
        let both = a
            .iter()
            .zip(&b)
            .filter(|(x, y)| **x != 0 && **y != 0)
            .count() as u64;
        assert_eq!(ra.intersection(&rb), both);
        assert_eq!(rb.intersection(&ra), both);
        assert_eq!(ra.intersection(&ra), ra.area());
    }

    #[test]
    fn relative_paths() {
        assert_eq!(
            relative(
                Path::new("/d/s/000000/rgb/000001.png"),
                Path::new("/d/s/000000")
            ),
            "rgb/000001.png"
        );
        assert_eq!(
            relative(Path::new("/d/s/000000/rgb/1.png"), Path::new("/d/out")),
            "../s/000000/rgb/1.png"
        );
    }
}
