//! JSON text exactly as bop_toolkit's `inout.save_json` writes it: a top-level dict with one
//! entry per line, each value as Python's `json.dumps(v, sort_keys=True)` (separators `", "`
//! and `": "`, floats as `repr(float)`, non-ASCII escaped).

use std::fmt::Write as _;

use serde_json::Value;

/// A `null` in data to be written. BOP files hold no nulls; serde_json turns NaN and
/// infinities into null, so a null here means a non-finite number slipped through.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NullValue;

/// Python's `repr(x)` for a float: shortest round-trip digits, `1.0` not `1`, exponent
/// form (`1e-05`, `1e+16`) below 1e-4 and from 1e16 on. `None` for NaN and infinities,
/// which JSON cannot hold.
pub fn py_float_repr(x: f64) -> Option<String> {
    let mut s = String::new();
    write_py_float(&mut s, x).then_some(s)
}

fn write_py_float(out: &mut String, x: f64) -> bool {
    if !x.is_finite() {
        return false;
    }
    if x == 0.0 {
        out.push_str(if x.is_sign_negative() { "-0.0" } else { "0.0" });
        return true;
    }
    if x < 0.0 {
        out.push('-');
    }
    // Rust's `{:e}` gives the shortest round-trip digits, as Python's repr does:
    // "1.2345e-5", "1e16".
    let sci = format!("{:e}", x.abs());
    let (mantissa, exp) = sci.split_once('e').unwrap_or((&sci, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let digits: String = mantissa.chars().filter(|c| *c != '.').collect();
    // The decimal point sits after `decpt` digits: x = 0.d1d2... * 10^decpt.
    let decpt = exp + 1;
    let n = digits.len() as i32;
    if decpt <= -4 || decpt > 16 {
        out.push_str(&digits[..1]);
        if n > 1 {
            out.push('.');
            out.push_str(&digits[1..]);
        }
        let sign = if exp < 0 { '-' } else { '+' };
        let _ = write!(out, "e{sign}{:02}", exp.unsigned_abs());
    } else if decpt <= 0 {
        out.push_str("0.");
        out.extend(std::iter::repeat_n('0', (-decpt) as usize));
        out.push_str(&digits);
    } else if decpt >= n {
        out.push_str(&digits);
        out.extend(std::iter::repeat_n('0', (decpt - n) as usize));
        out.push_str(".0");
    } else {
        out.push_str(&digits[..decpt as usize]);
        out.push('.');
        out.push_str(&digits[decpt as usize..]);
    }
    true
}

/// Python's `json.dumps` string escaping with `ensure_ascii=True`.
fn write_py_str(out: &mut String, s: &str) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            '\u{8}' => out.push_str("\\b"),
            '\u{c}' => out.push_str("\\f"),
            ' '..='~' => out.push(c),
            _ => {
                let mut buf = [0u16; 2];
                for unit in c.encode_utf16(&mut buf) {
                    let _ = write!(out, "\\u{unit:04x}");
                }
            }
        }
    }
    out.push('"');
}

/// Appends `json.dumps(value, sort_keys=True)` to `out`.
pub fn dumps_into(out: &mut String, value: &Value) -> Result<(), NullValue> {
    match value {
        Value::Null => return Err(NullValue),
        Value::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
        Value::Number(n) => {
            if let Some(i) = n.as_u64() {
                let _ = write!(out, "{i}");
            } else if let Some(i) = n.as_i64() {
                let _ = write!(out, "{i}");
            } else if !write_py_float(out, n.as_f64().unwrap_or(f64::NAN)) {
                return Err(NullValue);
            }
        }
        Value::String(s) => write_py_str(out, s),
        Value::Array(items) => {
            out.push('[');
            for (i, v) in items.iter().enumerate() {
                if i > 0 {
                    out.push_str(", ");
                }
                dumps_into(out, v)?;
            }
            out.push(']');
        }
        Value::Object(map) => {
            // Sorted here rather than relying on serde_json's map order, which the
            // `preserve_order` feature (enabled by any crate in the build) would change.
            let mut entries: Vec<(&String, &Value)> = map.iter().collect();
            entries.sort_by(|a, b| a.0.cmp(b.0));
            out.push('{');
            for (i, (k, v)) in entries.into_iter().enumerate() {
                if i > 0 {
                    out.push_str(", ");
                }
                write_py_str(out, k);
                out.push_str(": ");
                dumps_into(out, v)?;
            }
            out.push('}');
        }
    }
    Ok(())
}

/// `json.dumps(value, sort_keys=True)`.
pub fn dumps(value: &Value) -> Result<String, NullValue> {
    let mut s = String::new();
    dumps_into(&mut s, value)?;
    Ok(s)
}

/// The text of `save_json` for a dict: entries in the order given (callers pass them sorted:
/// numerically for image and object ids, as Python sorts int keys), no trailing newline.
pub fn save_json_dict<K, V, I>(entries: I) -> Result<String, NullValue>
where
    K: std::fmt::Display,
    V: std::borrow::Borrow<Value>,
    I: IntoIterator<Item = (K, V)>,
{
    let mut out = String::from("{\n");
    let mut first = true;
    for (k, v) in entries {
        if !first {
            out.push_str(",\n");
        }
        first = false;
        out.push_str("  ");
        write_py_str(&mut out, &k.to_string());
        out.push_str(": ");
        dumps_into(&mut out, v.borrow())?;
    }
    if !first {
        out.push('\n');
    }
    out.push('}');
    Ok(out)
}

/// `save_json_dict` for a JSON object, keys sorted as strings (camera.json).
pub fn save_json_object(value: &Value) -> Result<String, NullValue> {
    let Value::Object(map) = value else {
        return dumps(value);
    };
    let mut entries: Vec<(&String, &Value)> = map.iter().collect();
    entries.sort_by(|a, b| a.0.cmp(b.0));
    save_json_dict(entries)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use serde_json::json;

    fn r(x: f64) -> String {
        py_float_repr(x).unwrap()
    }

    #[test]
    fn float_repr_matches_python() {
        // Expected strings from CPython 3.11 `repr(float)`.
        let cases: &[(f64, &str)] = &[
            (1.0, "1.0"),
            (-1.0, "-1.0"),
            (0.0, "0.0"),
            (-0.0, "-0.0"),
            (0.1, "0.1"),
            (0.1 + 0.2, "0.30000000000000004"),
            (1e-5, "1e-05"),
            (1.5e-5, "1.5e-05"),
            (0.0001, "0.0001"),
            (0.00012345, "0.00012345"),
            (1e16, "1e+16"),
            (1.5e16, "1.5e+16"),
            (9999999999999998.0, "9999999999999998.0"),
            (1e15, "1000000000000000.0"),
            (123456789012345680.0, "1.2345678901234568e+17"),
            (1e100, "1e+100"),
            (1e-300, "1e-300"),
            (5e-324, "5e-324"),
            (f64::MAX, "1.7976931348623157e+308"),
            (572.4114, "572.4114"),
            (-0.999964, "-0.999964"),
            (123.456 * 1000.0, "123456.0"),
            (0.1234 * 1000.0, "123.39999999999999"),
            (2.0 / 3.0, "0.6666666666666666"),
            (100.0, "100.0"),
            (1234.5, "1234.5"),
        ];
        for &(x, want) in cases {
            assert_eq!(r(x), want, "repr({x:?})");
        }
        assert_eq!(py_float_repr(f64::NAN), None);
        assert_eq!(py_float_repr(f64::INFINITY), None);
    }

    #[test]
    fn float_repr_round_trips() {
        let mut x = 1.2345e-9f64;
        for _ in 0..400 {
            let s = r(x);
            assert_eq!(s.parse::<f64>().unwrap(), x, "{s}");
            x *= -1.7320508;
        }
    }

    #[test]
    fn dumps_like_python() {
        let v =
            json!({"obj_id": 3, "cam_t_m2c": [1.0, -2.5, 1e-7], "a": "é\"\n", "b": [], "c": {}});
        assert_eq!(
            dumps(&v).unwrap(),
            r#"{"a": "\u00e9\"\n", "b": [], "c": {}, "cam_t_m2c": [1.0, -2.5, 1e-07], "obj_id": 3}"#
        );
        assert_eq!(dumps(&json!("😀")).unwrap(), r#""\ud83d\ude00""#);
        assert_eq!(dumps(&json!([1, null])), Err(NullValue));
    }

    #[test]
    fn save_json_dict_layout() {
        let s = save_json_dict([(2, json!([1])), (10, json!({"x": 0.5}))]).unwrap();
        assert_eq!(s, "{\n  \"2\": [1],\n  \"10\": {\"x\": 0.5}\n}");
        assert_eq!(save_json_dict(Vec::<(u32, Value)>::new()).unwrap(), "{\n}");
        let cam = save_json_object(&json!({"width": 640, "cx": 1.5})).unwrap();
        assert_eq!(cam, "{\n  \"cx\": 1.5,\n  \"width\": 640\n}");
    }
}
