//! Arguments for running at scale: `--shard I/N` and `synthgen merge`.

use std::fmt;
use std::ops::Range;
use std::path::PathBuf;
use std::str::FromStr;

use clap::Args;

pub const MERGE_EXAMPLES: &str = "Examples:
  # Four shards of one 4000-frame run, then one dataset:
  for i in 0 1 2 3; do
    synthgen render --objects drill.obj --frames 4000 --seed 7 --shard $i/4 --out shards/$i &
  done; wait
  synthgen merge shards/0 shards/1 shards/2 shards/3 --out data/synth

Every file except synthgen.json comes out byte-identical to a single `synthgen render
--frames 4000 --seed 7` run: images are hard-linked (copied across file systems or with
--copy), scene folders split between shards get their JSON files united. All shards 0..N-1
must be present and finished. See docs/scaling.md for Slurm and Kubernetes.";

/// Shard `index` of `count`: a contiguous slice of a run's frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl Shard {
    /// The frames of this shard out of `frames` frames starting at `first`
    /// (`synthgen_jobs::render::shard_range`, what `render --shard` renders).
    pub fn range(&self, first: u64, frames: u64) -> Range<u64> {
        synthgen_jobs::render::shard_range(first, frames, self.index, self.count)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Shard, String> {
        let bad = || format!("expected I/N with 0 <= I < N, such as 0/4, got {s:?}");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: u64 = i.trim().parse().map_err(|_| bad())?;
        let count: u64 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Shard output folders of one `synthgen render --shard I/N` run (all N of them).
    #[arg(required = true, num_args = 1.., value_name = "DIR")]
    pub dirs: Vec<PathBuf>,

    /// Merged dataset folder.
    #[arg(long)]
    pub out: PathBuf,

    /// Copy files instead of hard-linking them.
    #[arg(long)]
    pub copy: bool,

    /// Replace the output in a non-empty --out that synthgen wrote (everything in it is
    /// removed first); a folder holding other files is refused.
    #[arg(long)]
    pub force: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_every_frame_once() {
        for count in 1..9u64 {
            for frames in [0u64, 1, 5, 17, 1000] {
                let mut next = 10;
                for index in 0..count {
                    let r = Shard { index, count }.range(10, frames);
                    assert_eq!(r.start, next);
                    assert!(r.end - r.start <= frames / count + 1);
                    next = r.end;
                }
                assert_eq!(next, 10 + frames);
            }
        }
        let huge = Shard { index: 2, count: 3 }.range(u64::MAX / 2, u64::MAX / 2);
        assert_eq!(huge.end, u64::MAX / 2 * 2);
    }

    #[test]
    fn shard_parsing() {
        assert_eq!("1/4".parse::<Shard>(), Ok(Shard { index: 1, count: 4 }));
        for bad in ["4/4", "1", "a/2", "0/0", "-1/3", "1/4/5"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
