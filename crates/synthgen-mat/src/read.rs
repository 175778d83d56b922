//! The reader: untrusted input, sizes checked before anything is allocated.

use std::collections::BTreeMap;
use std::io::{Read, Seek, SeekFrom};

use flate2::read::ZlibDecoder;

use super::{
    check_shape, decode, mi_size, word, word_at, MatArray, MatClass, MatError, ARRAY_COMPLEX,
    HEADER_LEN, MAX_DEFLATE_RATIO, MAX_INFLATED, MI_COMPRESSED, MI_INT32, MI_INT8, MI_MATRIX,
    MI_UINT8, MI_UTF8, PEEK,
};

/// One data element inside a buffer: `buf[start..start + len]` is its data.
struct Elem {
    ty: u32,
    start: usize,
    len: usize,
    /// Not clamped to the buffer: while peeking, the padding may not be read yet.
    next: usize,
}

/// Parses the tag at `pos`, including the small (data-in-tag) format.
/// `base` turns buffer positions into reported offsets.
fn elem(buf: &[u8], pos: usize, be: bool, base: u64) -> Result<Elem, MatError> {
    let (at, left) = (base + pos as u64, buf.len().saturating_sub(pos));
    let (Some(w0), Some(w1)) = (word_at(buf, pos, be), word_at(buf, pos + 4, be)) else {
        return Err(MatError::truncated(at, 8, left as u64));
    };
    let (ty, start, len) = match w0 >> 16 {
        0 => (w0, pos + 8, w1 as usize),
        small @ 1..=4 => (w0 & 0xffff, pos + 4, small as usize),
        n => {
            return Err(MatError::malformed(
                at,
                format!("small element of {n} bytes"),
            ))
        }
    };
    if start.checked_add(len).is_none_or(|end| end > buf.len()) {
        return Err(MatError::truncated(at, 8 + len as u64, left as u64));
    }
    let next = if start == pos + 4 {
        pos + 8
    } else {
        start + len.div_ceil(8) * 8
    };
    Ok(Elem {
        ty,
        start,
        len,
        next,
    })
}

fn elem_bytes<'a>(buf: &'a [u8], e: &Elem) -> &'a [u8] {
    buf.get(e.start..e.start + e.len).unwrap_or_default()
}

/// Flags, dims and name: what every miMATRIX starts with, whatever its class.
struct MatrixHeader {
    flags: u32,
    dims: Vec<usize>,
    name: String,
    /// Position of the real-part element.
    rest: usize,
}

fn parse_header(buf: &[u8], be: bool, base: u64) -> Result<MatrixHeader, MatError> {
    let f = elem(buf, 0, be, base)?;
    let flags = word_at(elem_bytes(buf, &f), 0, be)
        .ok_or_else(|| MatError::malformed(base, "array flags shorter than 4 bytes"))?;
    let d = elem(buf, f.next, be, base)?;
    let bad_dims = || MatError::malformed(base + f.next as u64, "dims are not 2+ int32 >= 0");
    if d.ty != MI_INT32 || d.len % 4 != 0 || d.len < 8 {
        return Err(bad_dims());
    }
    let dims: Vec<i32> = decode_vec!(elem_bytes(buf, &d), be, i32);
    let dims = dims
        .into_iter()
        .map(usize::try_from)
        .collect::<Result<Vec<_>, _>>();
    let dims = dims.map_err(|_| bad_dims())?;
    let n = elem(buf, d.next, be, base)?;
    if !matches!(n.ty, MI_INT8 | MI_UINT8 | MI_UTF8) {
        return Err(MatError::malformed(
            base + d.next as u64,
            "name is not a byte string",
        ));
    }
    let name = String::from_utf8_lossy(elem_bytes(buf, &n)).into_owned();
    Ok(MatrixHeader {
        flags,
        dims,
        name,
        rest: n.next,
    })
}

/// Whether the array flags (first element) name a numeric class, judged before the rest
/// of the header, which objects and other skipped classes lay out differently.
fn numeric_flags(buf: &[u8], be: bool) -> bool {
    let flags = elem(buf, 0, be, 0)
        .ok()
        .and_then(|f| word_at(elem_bytes(buf, &f), 0, be));
    flags.is_some_and(|w| MatClass::from_code(w & 0xff).is_some())
}

/// What one top-level element turned out to be.
enum Var {
    Numeric(String, MatArray),
    /// A wanted name holding something we do not decode; it still shadows earlier ones.
    /// The name is empty when unknown or absent.
    Other(String),
    /// Filtered out by `wanted`: left unverified, to stay cheap.
    Unwanted,
}

/// Where a miMATRIX body comes from, for reporting errors.
struct Ctx {
    /// Offset of the body's first byte (in the file, or in the inflated stream).
    base: u64,
    /// Offset of the enclosing miCOMPRESSED tag, if any.
    compressed_at: Option<u64>,
}

impl Ctx {
    /// Offsets inside inflated data mean nothing to a user; report the compressed element.
    fn wrap(&self, e: MatError) -> MatError {
        match (self.compressed_at, e) {
            (Some(at), e @ (MatError::Truncated { .. } | MatError::Malformed { .. })) => {
                MatError::corrupt(at, format!("in inflated data: {e}"))
            }
            (_, e) => e,
        }
    }

    /// Appends up to `n` bytes from `src` (a zlib decoder for compressed elements).
    fn fill(&self, src: &mut impl Read, buf: &mut Vec<u8>, n: u64) -> Result<(), MatError> {
        let read = src.take(n).read_to_end(buf);
        read.map(|_| ()).map_err(|e| match self.compressed_at {
            Some(at) => MatError::corrupt(at, e.to_string()),
            None => MatError::Io(e),
        })
    }
}

/// Reads a miMATRIX body of `size` bytes from `src`, which must hold at least that many
/// (or be a decoder whose output is capped). Variables filtered out by `wanted` cost
/// only the bytes up to their name.
fn read_matrix(
    src: &mut impl Read,
    size: u64,
    ctx: &Ctx,
    wanted: Option<&[&str]>,
    be: bool,
) -> Result<Var, MatError> {
    let short = |got: usize| ctx.wrap(MatError::truncated(ctx.base - 8, size + 8, got as u64 + 8));
    let mut buf = Vec::new();
    let mut want = PEEK.min(size);
    let header = loop {
        let missing = want - buf.len() as u64;
        ctx.fill(src, &mut buf, missing)?;
        if (buf.len() as u64) < want {
            return Err(short(buf.len()));
        }
        match parse_header(&buf, be, ctx.base) {
            Ok(h) => break h,
            Err(MatError::Truncated { .. }) if want < size => want = (want * 4).min(size),
            Err(_) if !numeric_flags(&buf, be) => return Ok(Var::Other(String::new())),
            Err(e) => return Err(ctx.wrap(e)),
        }
    };
    if wanted.is_some_and(|w| !w.contains(&header.name.as_str())) {
        return Ok(Var::Unwanted);
    }
    if header.name.is_empty() {
        return Ok(Var::Other(header.name)); // MATLAB's subsystem data, not a variable
    }
    let class = match MatClass::from_code(header.flags & 0xff) {
        Some(c) if header.flags & ARRAY_COMPLEX == 0 => c,
        _ => return Ok(Var::Other(header.name)),
    };
    let rest = size - buf.len() as u64;
    buf.reserve(usize::try_from(rest).unwrap_or(0));
    ctx.fill(src, &mut buf, rest)?;
    if (buf.len() as u64) < size {
        return Err(short(buf.len()));
    }
    let re = elem(&buf, header.rest, be, ctx.base).map_err(|e| ctx.wrap(e))?;
    let bytes = elem_bytes(&buf, &re);
    let data = match mi_size(re.ty) {
        Some(s) if bytes.len().is_multiple_of(s) => decode(re.ty, bytes, be),
        _ => None,
    };
    let Some(data) = data else {
        let reason = format!("{} bytes of type {} are not numbers", bytes.len(), re.ty);
        let at = ctx.base + header.rest as u64;
        return Err(ctx.wrap(MatError::malformed(at, reason)));
    };
    check_shape(&header.name, &header.dims, data.len())?;
    let (name, dims) = (header.name, header.dims);
    Ok(Var::Numeric(name, MatArray { dims, class, data }))
}

/// Reads a miCOMPRESSED element of `n` bytes whose tag is at `at`.
fn read_compressed(
    r: &mut impl Read,
    at: u64,
    n: u64,
    wanted: Option<&[&str]>,
    be: bool,
) -> Result<Var, MatError> {
    let ctx = Ctx {
        base: 8,
        compressed_at: Some(at),
    };
    let mut z = ZlibDecoder::new(r.take(n));
    let mut tag = Vec::with_capacity(8);
    ctx.fill(&mut z, &mut tag, 8)?;
    let (Some(ty), Some(size)) = (word_at(&tag, 0, be), word_at(&tag, 4, be)) else {
        let reason = format!("inflates to {} bytes, less than a tag", tag.len());
        return Err(MatError::corrupt(at, reason));
    };
    if ty != MI_MATRIX {
        return Ok(Var::Unwanted);
    }
    let size = u64::from(size);
    if size > MAX_INFLATED || size > n.saturating_mul(MAX_DEFLATE_RATIO) {
        let reason = format!(
            "declares {size} inflated bytes, more than {n} compressed bytes can hold or 1 GiB"
        );
        return Err(MatError::corrupt(at, reason));
    }
    let var = read_matrix(&mut z, size, &ctx, wanted, be)?;
    if !matches!(var, Var::Unwanted) {
        // zlib's checksum is only verified once the decoder reaches the stream's end.
        let rest = std::io::copy(&mut z.take(size + 64), &mut std::io::sink());
        rest.map_err(|e| MatError::corrupt(at, e.to_string()))?;
    }
    Ok(var)
}

/// Checks the 128-byte header; returns whether the file is big-endian.
fn read_header(r: &mut impl Read) -> Result<bool, MatError> {
    let mut h = Vec::with_capacity(HEADER_LEN as usize);
    r.take(HEADER_LEN).read_to_end(&mut h)?;
    if !(h.starts_with(b"MATLAB") || b"MATLAB".starts_with(&h)) {
        return Err(MatError::NotMatFile);
    }
    if h.starts_with(b"MATLAB 7.3") {
        return Err(MatError::V73);
    }
    let (Some(&[v0, v1]), Some(endian)) = (h.get(124..126), h.get(126..128)) else {
        return Err(MatError::TruncatedHeader(h.len() as u64));
    };
    let (be, version) = match endian {
        b"IM" => (false, u16::from_le_bytes([v0, v1])),
        b"MI" => (true, u16::from_be_bytes([v0, v1])),
        _ => return Err(MatError::NotMatFile),
    };
    match version >> 8 {
        1 => Ok(be),
        2 => Err(MatError::V73),
        _ => Err(MatError::UnsupportedVersion(version)),
    }
}

/// Reads the numeric variables of a MAT v5 file. `wanted`: only these names are decoded
/// (unwanted compressed variables are inflated only far enough to learn their name);
/// None = all. Logical arrays come back as UInt8; char, cell, struct, object, sparse
/// and complex variables are skipped. Duplicate names: the last wins, as in MATLAB.
pub fn read_mat<R: Read + Seek>(
    mut r: R,
    wanted: Option<&[&str]>,
) -> Result<BTreeMap<String, MatArray>, MatError> {
    let end = r.seek(SeekFrom::End(0))?;
    r.seek(SeekFrom::Start(0))?;
    let be = read_header(&mut r)?;
    let mut out = BTreeMap::new();
    let mut pos = HEADER_LEN;
    while pos < end {
        let left = end - pos;
        if left < 8 {
            return Err(MatError::truncated(pos, 8, left));
        }
        r.seek(SeekFrom::Start(pos))?;
        let mut t = [0u8; 8];
        r.read_exact(&mut t)?;
        let ty = word([t[0], t[1], t[2], t[3]], be);
        if ty >> 16 != 0 {
            pos += 8; // a small element: nothing we read fits in 4 bytes
            continue;
        }
        let n = u64::from(word([t[4], t[5], t[6], t[7]], be));
        if n > left - 8 {
            return Err(MatError::truncated(pos, 8 + n, left));
        }
        let var = match ty {
            MI_MATRIX => {
                let ctx = Ctx {
                    base: pos + 8,
                    compressed_at: None,
                };
                read_matrix(&mut (&mut r).take(n), n, &ctx, wanted, be)?
            }
            MI_COMPRESSED => read_compressed(&mut r, pos, n, wanted, be)?,
            _ => Var::Unwanted,
        };
        match var {
            Var::Numeric(name, array) => out.insert(name, array),
            Var::Other(name) => out.remove(&name),
            Var::Unwanted => None,
        };
        // Compressed elements are not padded; the final element's padding may be missing.
        let padded = if ty == MI_COMPRESSED {
            n
        } else {
            n.div_ceil(8) * 8
        };
        pos += 8 + padded.min(left - 8);
    }
    Ok(out)
}
