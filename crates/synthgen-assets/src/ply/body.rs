//! Readers of PLY body values: ASCII (one element instance per line, as every writer does and
//! plyfile requires) and binary little-endian. Both work on the file's bytes, without
//! allocating per line or per value.

use super::header::{Element, Kind, Scalar};

/// Why reading one element instance failed; the caller adds the element, index and file.
#[derive(Debug)]
pub(crate) enum Fail {
    Truncated,
    Bad(String),
    IndexOutOfRange(i64),
    NonFinite,
}

pub(crate) trait Body {
    /// Starts the next element instance.
    fn begin(&mut self) -> Result<(), Fail>;
    /// Reads one value of type `ty` as f64 (exact for every PLY type; `float` values are
    /// parsed as f32 so ASCII and binary files give bit-identical results).
    fn scalar(&mut self, ty: Scalar, prop: &str) -> Result<f64, Fail>;
    /// Ends the instance (ASCII: the line must have no values left).
    fn end(&mut self) -> Result<(), Fail>;
    /// 1-based line of the current instance, for ASCII.
    fn line(&self) -> Option<usize>;
    /// Skips all `el.count` instances of an element nobody reads; on failure returns the
    /// index of the instance where it failed.
    fn skip(&mut self, el: &Element) -> Result<(), (usize, Fail)>;

    /// Reads a list's length.
    fn count(&mut self, ty: Scalar, prop: &str) -> Result<usize, Fail> {
        let n = self.scalar(ty, prop)?;
        if n < 0.0 {
            return Err(Fail::Bad(format!("negative list length {n} for {prop}")));
        }
        Ok(n as usize)
    }

    /// Skips one instance generically, property by property.
    fn skip_instance(&mut self, el: &Element) -> Result<(), Fail> {
        self.begin()?;
        for p in &el.props {
            match p.kind {
                Kind::Scalar(t) => {
                    self.scalar(t, &p.name)?;
                }
                Kind::List { count, item } => {
                    for _ in 0..self.count(count, &p.name)? {
                        self.scalar(item, &p.name)?;
                    }
                }
            }
        }
        self.end()
    }
}

pub(crate) struct Ascii<'a> {
    text: &'a str,
    pos: usize,
    line: usize,
    tokens: std::str::SplitAsciiWhitespace<'a>,
}

impl<'a> Ascii<'a> {
    /// `first_line` is the 1-based line number of the body's first line.
    pub(crate) fn new(text: &'a str, first_line: usize) -> Self {
        Self {
            text,
            pos: 0,
            line: first_line.saturating_sub(1),
            tokens: "".split_ascii_whitespace(),
        }
    }
}

impl Body for Ascii<'_> {
    fn begin(&mut self) -> Result<(), Fail> {
        loop {
            if self.pos >= self.text.len() {
                return Err(Fail::Truncated);
            }
            let rest = &self.text[self.pos..];
            let len = rest.bytes().position(|b| b == b'\n').unwrap_or(rest.len());
            let l = &rest[..len];
            self.pos += len + 1;
            self.line += 1;
            if !l.trim_ascii().is_empty() {
                self.tokens = l.split_ascii_whitespace();
                return Ok(());
            }
        }
    }

    #[inline]
    fn scalar(&mut self, ty: Scalar, prop: &str) -> Result<f64, Fail> {
        let Some(tok) = self.tokens.next() else {
            return Err(Fail::Bad(format!(
                "line ends before property {prop}: fewer values than the header declares"
            )));
        };
        let bad = || Fail::Bad(format!("invalid {} value {tok:?} for {prop}", ty.name()));
        match ty {
            Scalar::F32 => tok.parse::<f32>().map(f64::from).map_err(|_| bad()),
            Scalar::F64 => tok.parse::<f64>().map_err(|_| bad()),
            _ => {
                let v = match tok.parse::<i64>() {
                    Ok(v) => v,
                    // Some writers print integers as "255.0".
                    Err(_) => match tok.parse::<f64>() {
                        Ok(f) if f.fract() == 0.0 && f.abs() < 9e15 => f as i64,
                        _ => return Err(bad()),
                    },
                };
                let (lo, hi) = ty.int_range();
                if v < lo || v > hi {
                    return Err(Fail::Bad(format!(
                        "value {v} out of range for {} property {prop}",
                        ty.name()
                    )));
                }
                Ok(v as f64)
            }
        }
    }

    fn end(&mut self) -> Result<(), Fail> {
        match self.tokens.next() {
            None => Ok(()),
            Some(t) => Err(Fail::Bad(format!(
                "unexpected value {t:?}: more values than the header declares"
            ))),
        }
    }

    fn line(&self) -> Option<usize> {
        Some(self.line)
    }

    fn skip(&mut self, el: &Element) -> Result<(), (usize, Fail)> {
        for i in 0..el.count {
            self.begin().map_err(|f| (i, f))?;
        }
        Ok(())
    }
}

pub(crate) struct Binary<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Binary<'a> {
    pub(crate) fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    #[inline]
    fn take<const N: usize>(&mut self) -> Result<[u8; N], Fail> {
        let end = self.pos + N;
        let bytes: [u8; N] = self
            .data
            .get(self.pos..end)
            .and_then(|s| s.try_into().ok())
            .ok_or(Fail::Truncated)?;
        self.pos = end;
        Ok(bytes)
    }
}

impl Body for Binary<'_> {
    fn begin(&mut self) -> Result<(), Fail> {
        Ok(())
    }

    #[inline]
    fn scalar(&mut self, ty: Scalar, _prop: &str) -> Result<f64, Fail> {
        Ok(match ty {
            Scalar::I8 => f64::from(i8::from_le_bytes(self.take()?)),
            Scalar::U8 => f64::from(u8::from_le_bytes(self.take()?)),
            Scalar::I16 => f64::from(i16::from_le_bytes(self.take()?)),
            Scalar::U16 => f64::from(u16::from_le_bytes(self.take()?)),
            Scalar::I32 => f64::from(i32::from_le_bytes(self.take()?)),
            Scalar::U32 => f64::from(u32::from_le_bytes(self.take()?)),
            Scalar::F32 => f64::from(f32::from_le_bytes(self.take()?)),
            Scalar::F64 => f64::from_le_bytes(self.take()?),
        })
    }

    fn end(&mut self) -> Result<(), Fail> {
        Ok(())
    }

    fn line(&self) -> Option<usize> {
        None
    }

    fn skip(&mut self, el: &Element) -> Result<(), (usize, Fail)> {
        if let Some(stride) = el.fixed_stride() {
            let left = self.data.len() - self.pos;
            let need = stride.saturating_mul(el.count);
            if need > left {
                return Err((left / stride.max(1), Fail::Truncated));
            }
            self.pos += need;
            return Ok(());
        }
        for i in 0..el.count {
            self.skip_instance(el).map_err(|f| (i, f))?;
        }
        Ok(())
    }
}
