//! Length units of a model file, and the conversion of raw coordinates to metres.

use std::fmt;
use std::str::FromStr;

use synthgen_core::Model;

use crate::Error;

/// Units of the coordinates stored in a model file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Units {
    /// Millimetres (BOP and Linemod models).
    Mm,
    /// Metres (glTF by spec, most OBJ exports such as YCB).
    M,
    /// Decide from the size of the model, see [`AUTO_MM_THRESHOLD`].
    #[default]
    Auto,
}

/// With [`Units::Auto`], a model whose raw bounding-box diagonal exceeds this is read as
/// millimetres, otherwise as metres. Objects for grasping are 2 cm to 1 m: in metres their
/// diagonal is at most about 1.7, in millimetres at least 20. 5 sits between with margin on
/// both sides; only a model outside that range (a 5 m object, or a 5 mm one) is misjudged.
pub const AUTO_MM_THRESHOLD: f64 = 5.0;

impl Units {
    /// Metres per raw unit; `None` for `Auto`.
    pub fn metres_per_unit(self) -> Option<f32> {
        match self {
            Units::Mm => Some(0.001),
            Units::M => Some(1.0),
            Units::Auto => None,
        }
    }

    fn long_name(self) -> &'static str {
        match self {
            Units::Mm => "millimetres",
            Units::M => "metres",
            Units::Auto => "auto",
        }
    }
}

impl fmt::Display for Units {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Units::Mm => "mm",
            Units::M => "m",
            Units::Auto => "auto",
        })
    }
}

impl FromStr for Units {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "mm" | "millimetres" | "millimeters" => Ok(Units::Mm),
            "m" | "metres" | "meters" => Ok(Units::M),
            "auto" => Ok(Units::Auto),
            _ => Err(Error::UnknownUnits {
                value: s.to_string(),
            }),
        }
    }
}

/// Scales `model` (raw file coordinates) to metres. Returns the units used (never `Auto`) and,
/// for `Auto`, a note saying what was decided and why.
pub(crate) fn apply_units(model: &mut Model, units: Units) -> (Units, Option<String>) {
    let (used, note) = match units {
        Units::Auto => {
            let diagonal = model
                .aabb()
                .map(|bb| f64::from(bb.size().length()))
                .unwrap_or(0.0);
            let used = if diagonal > AUTO_MM_THRESHOLD {
                Units::Mm
            } else {
                Units::M
            };
            let file = model
                .source
                .file_name()
                .map(|f| f.to_string_lossy().into_owned())
                .unwrap_or_else(|| model.name.clone());
            let note = format!(
                "auto units: {file} bbox diagonal {diagonal:.1} → {}",
                used.long_name()
            );
            (used, Some(note))
        }
        u => (u, None),
    };
    if used == Units::Mm {
        // Dividing (not multiplying by the inexact 0.001) gives the correctly rounded metre
        // value of every raw coordinate: 5 mm becomes exactly the f32 nearest 0.005.
        for p in &mut model.primitives {
            for v in &mut p.positions_m {
                *v /= 1000.0;
            }
        }
    }
    (used, note)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::Vec3;

    #[test]
    fn parse_and_display_round_trip() {
        for u in [Units::Mm, Units::M, Units::Auto] {
            assert_eq!(u.to_string().parse::<Units>().unwrap(), u);
        }
        assert_eq!("MM".parse::<Units>().unwrap(), Units::Mm);
        let err = "cm".parse::<Units>().unwrap_err().to_string();
        assert!(
            err.contains("\"cm\"") && err.contains("mm, m or auto"),
            "{err}"
        );
    }

    #[test]
    fn auto_picks_mm_for_large_and_m_for_small_models() {
        let mut big = Model::cuboid("big", Vec3::splat(100.0));
        let (u, note) = apply_units(&mut big, Units::Auto);
        assert_eq!(u, Units::Mm);
        assert!(note.unwrap().contains("millimetres"));
        assert!((big.aabb().unwrap().size().x - 0.1).abs() < 1e-6);

        let mut small = Model::cuboid("small", Vec3::splat(0.1));
        let (u, note) = apply_units(&mut small, Units::Auto);
        assert_eq!(u, Units::M);
        assert!(note.unwrap().contains("→ metres"));
        assert!((small.aabb().unwrap().size().x - 0.1).abs() < 1e-6);
    }

    #[test]
    fn explicit_units_override_the_size() {
        let mut m = Model::cuboid("c", Vec3::splat(0.1));
        let (u, note) = apply_units(&mut m, Units::Mm);
        assert_eq!(u, Units::Mm);
        assert!(note.is_none());
        assert!((m.aabb().unwrap().size().x - 0.0001).abs() < 1e-9);
    }
}
