//! The small pieces every part of the scene spec checks its values with: a sampled range,
//! the `[min, max]` check, and the refusal of a file whose arrays the parse would drop.

use crate::Error;

/// A closed range `[min, max]` sampled uniformly.
pub type Range = [f64; 2];

pub(crate) fn check_range(name: &str, r: Range, min: f64, max: f64) -> Result<(), Error> {
    let [lo, hi] = r;
    if !(lo.is_finite() && hi.is_finite() && min <= lo && lo <= hi && hi <= max) {
        return Err(Error::InvalidSpec(format!(
            "{name} must be [min, max] with {min} <= min <= max <= {max}, got [{lo}, {hi}]"
        )));
    }
    Ok(())
}

/// An error naming the first array of `given` (the file as written) that the parsed spec
/// holds fewer values of, e.g. `camera_pose.distance_m = [0.5, 0.8, 1.2]`.
pub(crate) fn check_nothing_dropped(
    given: &toml::Value,
    kept: &toml::Value,
    path: &str,
) -> Result<(), Error> {
    use toml::Value;
    match (given, kept) {
        (Value::Table(g), Value::Table(k)) => {
            for (key, gv) in g {
                if let Some(kv) = k.get(key) {
                    let p = if path.is_empty() {
                        key.clone()
                    } else {
                        format!("{path}.{key}")
                    };
                    check_nothing_dropped(gv, kv, &p)?;
                }
            }
            Ok(())
        }
        (Value::Array(g), Value::Array(k)) if g.len() > k.len() => Err(Error::InvalidSpec(
            format!("{path} has {} values but takes {}", g.len(), k.len()),
        )),
        (Value::Array(g), Value::Array(k)) => {
            for (i, (gv, kv)) in g.iter().zip(k).enumerate() {
                check_nothing_dropped(gv, kv, &format!("{path}[{i}]"))?;
            }
            Ok(())
        }
        _ => Ok(()),
    }
}
