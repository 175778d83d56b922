//! Frames that are the same image under different names: the same file, a hard link to it,
//! or a copy with the same bytes. A mix, and an experiment, must never train on its own test
//! frames.

use std::collections::HashMap;
use std::hash::Hasher;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::source::SourceFrame;

/// What identifies a frame's colour image without reading it.
struct Identity {
    canonical: PathBuf,
    /// (device, inode) where the platform has them: hard links share it.
    inode: Option<(u64, u64)>,
    len: u64,
}

fn identity(rgb: &Path) -> Result<Identity> {
    let meta = std::fs::metadata(rgb).map_err(|e| Error::io("read", rgb, e))?;
    #[cfg(unix)]
    let inode = {
        use std::os::unix::fs::MetadataExt;
        Some((meta.dev(), meta.ino()))
    };
    #[cfg(not(unix))]
    let inode = None;
    Ok(Identity {
        canonical: rgb.canonicalize().unwrap_or_else(|_| rgb.to_path_buf()),
        inode,
        len: meta.len(),
    })
}

fn content_hash(path: &Path) -> Result<u64> {
    let bytes = crate::io::read(path)?;
    let mut h = std::collections::hash_map::DefaultHasher::new();
    h.write(&bytes);
    Ok(h.finish())
}

/// For each of `others` that is the same image as one of `frames` (same path, same inode,
/// or same size and bytes), its index and that frame's index. Files are only read when two
/// have the same size, so distinct datasets cost one `stat` per frame.
pub fn same_images(
    frames: &[&SourceFrame],
    others: &[&SourceFrame],
) -> Result<Vec<(usize, usize)>> {
    let ids = frames
        .iter()
        .map(|f| identity(&f.rgb))
        .collect::<Result<Vec<_>>>()?;
    let mut by_path: HashMap<&Path, usize> = HashMap::new();
    let mut by_inode: HashMap<(u64, u64), usize> = HashMap::new();
    let mut by_len: HashMap<u64, Vec<usize>> = HashMap::new();
    for (i, id) in ids.iter().enumerate() {
        by_path.entry(id.canonical.as_path()).or_insert(i);
        if let Some(n) = id.inode {
            by_inode.entry(n).or_insert(i);
        }
        by_len.entry(id.len).or_default().push(i);
    }
    let mut hashes: HashMap<usize, u64> = HashMap::new();
    let mut out = Vec::new();
    for (j, f) in others.iter().enumerate() {
        let id = identity(&f.rgb)?;
        let same = by_path
            .get(id.canonical.as_path())
            .or_else(|| id.inode.and_then(|n| by_inode.get(&n)))
            .copied();
        if let Some(i) = same {
            out.push((j, i));
            continue;
        }
        let Some(candidates) = by_len.get(&id.len) else {
            continue;
        };
        let h = content_hash(&f.rgb)?;
        for &i in candidates {
            let hi = match hashes.get(&i) {
                Some(&v) => v,
                None => {
                    let v = content_hash(&frames[i].rgb)?;
                    hashes.insert(i, v);
                    v
                }
            };
            if hi == h && crate::io::read(&frames[i].rgb)? == crate::io::read(&f.rgb)? {
                out.push((j, i));
                break;
            }
        }
    }
    Ok(out)
}
