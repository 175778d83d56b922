//! What a dataset folder holds, cheaply: the sorted list of its files with their sizes and
//! modification times, hashed. A resumed experiment compares it with what its finished steps
//! read, so that frames deleted, files rewritten, or another dataset put under the same path
//! are noticed instead of mixed into old results.

use std::path::Path;
use std::time::UNIX_EPOCH;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A dataset folder's files (hidden ones left out: locks, run plans), their total size and a
/// hash of "relative path, size, modification time" per file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fingerprint {
    pub files: u64,
    pub bytes: u64,
    /// FNV-1a (64 bit) of the sorted `path\tsize\tmtime_ns` lines, hex.
    pub hash: String,
}

/// Deeper folders than this are not walked (BOP's root/split/scene/rgb/file is 4 deep).
const MAX_DEPTH: usize = 8;

/// The fingerprint of the folder `root` (a missing folder is [`Error::NoSuchDataset`]). A copy
/// that does not keep modification times counts as a change: the safe side.
pub fn fingerprint(root: &Path) -> Result<Fingerprint> {
    if !root.is_dir() {
        return Err(Error::NoSuchDataset {
            path: root.to_path_buf(),
        });
    }
    let (mut lines, mut files, mut bytes) = (Vec::new(), 0u64, 0u64);
    let mut stack = vec![(root.to_path_buf(), 0usize)];
    while let Some((dir, depth)) = stack.pop() {
        let entries = std::fs::read_dir(&dir).map_err(|e| Error::io("read", &dir, e))?;
        for e in entries {
            let e = e.map_err(|e| Error::io("list directory", &dir, e))?;
            if e.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            let p = e.path();
            let rel = p.strip_prefix(root).unwrap_or(&p).display().to_string();
            // Follows links, as the readers do; a broken one is a line of its own.
            let Ok(meta) = std::fs::metadata(&p) else {
                lines.push(format!("{rel}\tbroken"));
                continue;
            };
            if meta.is_dir() {
                if depth < MAX_DEPTH {
                    stack.push((p, depth + 1));
                }
                continue;
            }
            let ns = meta
                .modified()
                .ok()
                .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
                .map_or(0, |d| d.as_nanos());
            lines.push(format!("{rel}\t{}\t{ns}", meta.len()));
            files += 1;
            bytes += meta.len();
        }
    }
    lines.sort_unstable();
    Ok(Fingerprint {
        files,
        bytes,
        hash: format!("{:016x}", fnv1a(lines.join("\n").as_bytes())),
    })
}

/// 64-bit FNV-1a.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_reference_values() {
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn a_removed_or_rewritten_file_changes_it_a_hidden_one_does_not() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("train/000000/rgb")).unwrap();
        for i in 0..3 {
            std::fs::write(d.join(format!("train/000000/rgb/{i:06}.png")), b"png").unwrap();
        }
        std::fs::write(d.join("camera.json"), b"{}").unwrap();
        let a = fingerprint(d).unwrap();
        assert_eq!((a.files, a.bytes), (4, 11));
        assert_eq!(fingerprint(d).unwrap(), a, "deterministic");
        std::fs::write(d.join(".synthgen.lock"), b"").unwrap();
        assert_eq!(fingerprint(d).unwrap(), a, "hidden files do not count");
        // The same bytes written again at another time: a change.
        let f = std::fs::File::options()
            .write(true)
            .open(d.join("camera.json"))
            .unwrap();
        f.set_modified(UNIX_EPOCH + std::time::Duration::from_secs(1))
            .unwrap();
        let b = fingerprint(d).unwrap();
        assert_eq!((b.files, b.bytes), (4, 11));
        assert_ne!(b.hash, a.hash);
        std::fs::remove_file(d.join("train/000000/rgb/000001.png")).unwrap();
        assert_eq!(fingerprint(d).unwrap().files, 3);
        assert!(matches!(
            fingerprint(&d.join("gone")),
            Err(Error::NoSuchDataset { .. })
        ));
    }
}
