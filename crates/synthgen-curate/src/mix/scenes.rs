//! A test split of whole scenes (`--test-scenes`): every real frame of the named scenes is
//! held out and training draws only from the other scenes. Consecutive video frames are
//! near-duplicates, so a random frame split would test on frames the model has all but seen.

use std::collections::BTreeSet;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use synthgen_formats::source::FrameLocation;
use synthgen_formats::{Error, Result};

/// A scene of a dataset: `ID` (that scene id in every split) or `SPLIT/ID` (in one split).
/// Serialized as that string.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct SceneRef {
    pub split: Option<String>,
    pub scene_id: u32,
}

impl SceneRef {
    pub fn matches(&self, loc: &FrameLocation) -> bool {
        loc.scene_id == self.scene_id && self.split.as_ref().is_none_or(|s| *s == loc.split)
    }
}

impl fmt::Display for SceneRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.split {
            Some(s) => write!(f, "{s}/{}", self.scene_id),
            None => write!(f, "{}", self.scene_id),
        }
    }
}

impl FromStr for SceneRef {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<SceneRef, String> {
        let s = s.trim();
        let (split, id) = match s.rsplit_once('/') {
            Some((split, id)) if !split.is_empty() => (Some(split.to_string()), id),
            _ => (None, s),
        };
        let scene_id = id.parse().map_err(|_| {
            format!("{s:?} is not a scene id (a number such as 2, or SPLIT/ID such as test/2)")
        })?;
        Ok(SceneRef { split, scene_id })
    }
}

impl Serialize for SceneRef {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for SceneRef {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<SceneRef, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// The scenes of `locations` as `--test-scenes` would name them: plain ids when the dataset
/// has one split, `SPLIT/ID` otherwise; sorted, distinct.
pub fn available_scenes(locations: &[&FrameLocation]) -> Vec<String> {
    let scenes: BTreeSet<(&str, u32)> = locations
        .iter()
        .map(|l| (l.split.as_str(), l.scene_id))
        .collect();
    let splits: BTreeSet<&str> = scenes.iter().map(|s| s.0).collect();
    let mut out: Vec<(u32, String)> = scenes
        .iter()
        .map(|&(split, id)| {
            let name = if splits.len() > 1 {
                format!("{split}/{id}")
            } else {
                id.to_string()
            };
            (id, name)
        })
        .collect();
    out.sort();
    out.into_iter().map(|(_, n)| n).collect()
}

/// The indices (sorted) of the frames in `scenes`. A scene no frame belongs to is an error
/// that lists the dataset's scenes; so is an empty list.
pub fn scene_test_frames(
    locations: &[&FrameLocation],
    scenes: &[SceneRef],
    path: &Path,
) -> Result<Vec<usize>> {
    if scenes.is_empty() {
        return Err(Error::InvalidRequest(
            "no test scenes given: name at least one scene to hold out".into(),
        ));
    }
    let unknown: Vec<String> = scenes
        .iter()
        .filter(|s| !locations.iter().any(|l| s.matches(l)))
        .map(SceneRef::to_string)
        .collect();
    if !unknown.is_empty() {
        return Err(Error::UnknownScenes {
            asked: unknown.join(", "),
            available: available_scenes(locations).join(", "),
            path: path.to_path_buf(),
        });
    }
    Ok(locations
        .iter()
        .enumerate()
        .filter(|(_, l)| scenes.iter().any(|s| s.matches(l)))
        .map(|(i, _)| i)
        .collect())
}

/// `scenes` as a comma-separated list ("0, 2").
pub fn scene_list(scenes: &[SceneRef]) -> String {
    scenes
        .iter()
        .map(SceneRef::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn loc(split: &str, scene_id: u32, im_id: u32) -> FrameLocation {
        FrameLocation {
            split: split.into(),
            scene_id,
            im_id,
        }
    }

    #[test]
    fn scene_refs_parse_and_print() {
        let r: SceneRef = "2".parse().unwrap();
        assert_eq!((r.split.as_deref(), r.scene_id), (None, 2));
        let r: SceneRef = " test/0002 ".parse().unwrap();
        assert_eq!((r.split.as_deref(), r.scene_id), (Some("test"), 2));
        assert_eq!(r.to_string(), "test/2");
        assert!("x".parse::<SceneRef>().is_err());
        assert!("test/".parse::<SceneRef>().is_err());
        assert!("-1".parse::<SceneRef>().is_err());
        let json = serde_json::to_string(&vec![r.clone(), "0".parse().unwrap()]).unwrap();
        assert_eq!(json, r#"["test/2","0"]"#);
        let back: Vec<SceneRef> = serde_json::from_str(&json).unwrap();
        assert_eq!(back[0], r);
    }

    #[test]
    fn a_scene_id_matches_in_every_split_unless_one_is_named() {
        let locs = [loc("train", 0, 1), loc("test", 0, 1), loc("train", 1, 1)];
        let refs: Vec<&FrameLocation> = locs.iter().collect();
        let p = Path::new("/d");
        let all = scene_test_frames(&refs, &["0".parse().unwrap()], p).unwrap();
        assert_eq!(all, [0, 1]);
        let one = scene_test_frames(&refs, &["test/0".parse().unwrap()], p).unwrap();
        assert_eq!(one, [1]);
        let e = scene_test_frames(
            &refs,
            &["7".parse().unwrap(), "train/9".parse().unwrap()],
            p,
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "no scene 7, train/9 in the dataset; its scenes are test/0, train/0, train/1: /d"
        );
        assert!(scene_test_frames(&refs, &[], p).is_err());
    }
}
