//! PLY header: format, elements and their properties.

use std::path::Path;

use crate::Error;

/// A PLY scalar type (both the old names `uchar`, `float` and the sized ones `uint8`, `float32`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    pub(crate) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub(crate) fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Inclusive value range of an integer type.
    pub(crate) fn int_range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
pub(crate) struct Property {
    pub name: String,
    pub kind: Kind,
}

#[derive(Debug, Clone)]
pub(crate) struct Element {
    pub name: String,
    pub count: usize,
    pub props: Vec<Property>,
}

impl Element {
    /// Bytes per instance in binary when no property is a list.
    pub(crate) fn fixed_stride(&self) -> Option<usize> {
        self.props
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => Some(s.size()),
                Kind::List { .. } => None,
            })
            .sum()
    }

    pub(crate) fn prop(&self, name: &str) -> Option<&Property> {
        self.props.iter().find(|p| p.name == name)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Format {
    Ascii,
    BinaryLittleEndian,
}

#[derive(Debug, Clone)]
pub(crate) struct Header {
    pub format: Format,
    pub elements: Vec<Element>,
    /// `comment TextureFile NAME` (MeshLab, BOP's textured models).
    pub texture_file: Option<String>,
    /// Byte offset of the body.
    pub body_start: usize,
    /// Number of header lines, so ASCII body lines can be numbered.
    pub lines: usize,
}

pub(crate) fn parse_header(bytes: &[u8], path: &Path) -> Result<Header, Error> {
    let err = |line: usize, reason: String| Error::PlyHeader {
        line,
        reason,
        path: path.to_path_buf(),
    };
    if bytes.is_empty() {
        return Err(err(1, "file is empty".into()));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut texture_file = None;
    let mut pos = 0usize;
    let mut line_no = 0usize;
    loop {
        if pos >= bytes.len() {
            return Err(err(line_no, "file ends before end_header".into()));
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| pos + i);
        let raw = &bytes[pos..end];
        pos = (end + 1).min(bytes.len());
        line_no += 1;
        let Ok(line) = std::str::from_utf8(raw) else {
            return Err(err(line_no, "header line is not text".into()));
        };
        let line = line.trim_end_matches('\r');
        if line_no == 1 {
            if line.trim() != "ply" {
                return Err(err(1, "not a ply file (first line is not \"ply\")".into()));
            }
            continue;
        }
        let mut words = line.split_ascii_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "format" => {
                format = Some(match words.next() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::BinaryLittleEndian,
                    Some("binary_big_endian") => {
                        return Err(Error::UnsupportedPly {
                            reason: "binary_big_endian is not supported; \
                                     convert to ascii or binary_little_endian"
                                .into(),
                            path: path.to_path_buf(),
                        })
                    }
                    other => {
                        return Err(err(
                            line_no,
                            format!("unknown format {:?}", other.unwrap_or("")),
                        ))
                    }
                });
            }
            "comment" | "obj_info" => {
                if keyword == "comment" && words.next() == Some("TextureFile") {
                    let name = line.split_once("TextureFile").map_or("", |(_, n)| n.trim());
                    if !name.is_empty() {
                        texture_file = Some(name.to_string());
                    }
                }
            }
            "element" => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(err(line_no, "expected \"element NAME COUNT\"".into()));
                };
                let count = count
                    .parse::<usize>()
                    .map_err(|_| err(line_no, format!("invalid element count {count:?}")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            "property" => {
                let Some(el) = elements.last_mut() else {
                    return Err(err(line_no, "property before any element".into()));
                };
                let ty = |w: Option<&str>| {
                    let w = w.unwrap_or("");
                    Scalar::parse(w).ok_or_else(|| err(line_no, format!("unknown type {w:?}")))
                };
                let first = words.next();
                let kind = if first == Some("list") {
                    let count = ty(words.next())?;
                    if count.is_float() {
                        return Err(err(line_no, "list count type must be an integer".into()));
                    }
                    Kind::List {
                        count,
                        item: ty(words.next())?,
                    }
                } else {
                    Kind::Scalar(ty(first)?)
                };
                let (Some(name), None) = (words.next(), words.next()) else {
                    return Err(err(line_no, "expected \"property TYPE NAME\"".into()));
                };
                el.props.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            "end_header" => break,
            other => return Err(err(line_no, format!("unknown keyword {other:?}"))),
        }
    }
    let Some(format) = format else {
        return Err(err(line_no, "no format line".into()));
    };
    Ok(Header {
        format,
        elements,
        texture_file,
        body_start: pos,
        lines: line_no,
    })
}
