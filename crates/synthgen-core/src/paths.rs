//! Where a command may write: the one rule every command shares is that an output is never
//! one of its inputs, never inside one and never contains one ([`overlap`]), whatever spelling
//! (`a/../a`, a link, a trailing `/`) names them; and a name read from a file (an MTL's
//! texture, a JSON's path) never leaves the folder it is joined to ([`plain_relative`]).

use std::path::{Component, Path, PathBuf};

/// `path` made absolute without needing it to exist: the deepest existing ancestor is
/// canonicalized (resolving links), the rest appended with `.`/`..` folded.
pub fn resolve(path: &Path) -> PathBuf {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut existing = abs.as_path();
    let mut rest: Vec<Component> = Vec::new();
    loop {
        if let Ok(c) = existing.canonicalize() {
            let mut out = c;
            for comp in rest.iter().rev() {
                match comp {
                    Component::ParentDir => {
                        out.pop();
                    }
                    Component::CurDir => {}
                    c => out.push(c.as_os_str()),
                }
            }
            return out;
        }
        match (existing.parent(), existing.components().next_back()) {
            (Some(parent), Some(last)) => {
                rest.push(last);
                existing = parent;
            }
            _ => return abs,
        }
    }
}

/// How an output path stands to an input path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overlap {
    /// The same file or folder.
    Is,
    /// The output lies inside the input folder.
    LiesInside,
    /// The output folder contains the input (a `--force` would remove it).
    Contains,
}

impl Overlap {
    /// "is", "lies inside", "contains": reads as `the output X {} the input Y`.
    pub fn verb(self) -> &'static str {
        match self {
            Overlap::Is => "is",
            Overlap::LiesInside => "lies inside",
            Overlap::Contains => "contains",
        }
    }
}

/// Whether `output` is, lies inside or contains `input`, both resolved ([`resolve`]).
pub fn overlap(output: &Path, input: &Path) -> Option<Overlap> {
    let (out, inp) = (resolve(output), resolve(input));
    if out == inp {
        Some(Overlap::Is)
    } else if out.starts_with(&inp) {
        Some(Overlap::LiesInside)
    } else if inp.starts_with(&out) {
        Some(Overlap::Contains)
    } else {
        None
    }
}

/// The first input (role, path) that `output` overlaps, with how.
pub fn first_overlap<'a, R: AsRef<Path>>(
    output: &Path,
    inputs: &'a [(&'a str, R)],
) -> Option<(Overlap, &'a str, &'a Path)> {
    inputs.iter().find_map(|(role, input)| {
        overlap(output, input.as_ref()).map(|o| (o, *role, input.as_ref()))
    })
}

/// `name` (read from a file: an MTL's texture, an OBJ's `mtllib`) as a relative path that
/// stays inside whatever folder it is joined to: only plain components, no root, no drive, no
/// `..`, no empty name. None when it is not one; the caller then refuses it or stores the
/// file under a safe name of its own.
pub fn plain_relative(name: &str) -> Option<PathBuf> {
    let p = Path::new(name);
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::Normal(s) => out.push(s),
            Component::CurDir => {}
            Component::ParentDir | Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    let windows_drive = name.len() >= 2 && name.as_bytes()[1] == b':';
    (!out.as_os_str().is_empty() && !name.contains('\0') && !windows_drive).then_some(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn overlaps_are_found_whatever_the_spelling() {
        let d = std::env::temp_dir().join(format!("synthgen-paths-{}", std::process::id()));
        let inp = d.join("in");
        std::fs::create_dir_all(inp.join("sub")).unwrap();
        std::fs::write(inp.join("f.json"), "{}").unwrap();
        assert_eq!(overlap(&inp, &inp), Some(Overlap::Is));
        assert_eq!(overlap(&d.join("in/../in/"), &inp), Some(Overlap::Is));
        assert_eq!(
            overlap(&inp.join("f.json"), &inp),
            Some(Overlap::LiesInside)
        );
        assert_eq!(
            overlap(&inp.join("sub/new/x"), &inp),
            Some(Overlap::LiesInside)
        );
        assert_eq!(overlap(&d, &inp.join("f.json")), Some(Overlap::Contains));
        assert_eq!(
            overlap(&inp.join("f.json"), &inp.join("f.json")),
            Some(Overlap::Is)
        );
        assert_eq!(overlap(&d.join("in2"), &inp), None);
        assert_eq!(overlap(&d.join("other"), &inp), None);
        let inputs = [("dataset", inp.clone())];
        let (o, role, _) = first_overlap(&inp.join("x"), &inputs).unwrap();
        assert_eq!((o, role), (Overlap::LiesInside, "dataset"));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn names_from_files_stay_inside() {
        assert_eq!(plain_relative("a.png").unwrap(), PathBuf::from("a.png"));
        assert_eq!(
            plain_relative("./tex/a.png").unwrap(),
            PathBuf::from("tex/a.png")
        );
        for bad in [
            "../a.png",
            "tex/../../a.png",
            "/etc/passwd",
            "",
            ".",
            "C:x.png",
        ] {
            assert!(plain_relative(bad).is_none(), "{bad}");
        }
        // `..` anywhere is refused, even where it would fold back inside.
        assert!(plain_relative("tex/../a.png").is_none());
    }
}
