//! The writer: deterministic little-endian MAT v5, as MATLAB and scipy load it.

use std::io::Write;

use flate2::{write::ZlibEncoder, Compression};

use super::{
    check_shape, mi_size, MatArray, MatError, HEADER_LEN, HEADER_TEXT, MI_COMPRESSED, MI_INT32,
    MI_INT8, MI_MATRIX, MI_UINT32,
};

/// `len` must fit u32 (`validate` ensures it).
fn push_elem(out: &mut Vec<u8>, ty: u32, len: usize, data: impl FnOnce(&mut Vec<u8>)) {
    let len32 = u32::try_from(len).unwrap_or(u32::MAX);
    if (1..=4).contains(&len) {
        out.extend_from_slice(&(len32 << 16 | ty).to_le_bytes());
    } else {
        out.extend_from_slice(&ty.to_le_bytes());
        out.extend_from_slice(&len32.to_le_bytes());
    }
    data(out);
    out.resize(out.len().div_ceil(8) * 8, 0);
}

/// MATLAB's `isvarname`; other names load badly or not at all (scipy drops `_x`).
fn valid_name(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
        && name.len() <= 63
}

/// Checks that MATLAB can load the variable; returns its dims as stored and data bytes.
fn validate(name: &str, a: &MatArray) -> Result<(Vec<i32>, usize), MatError> {
    if !valid_name(name) {
        let rule = "names need a letter then letters, digits or '_', at most 63 characters";
        return Err(MatError::unwritable(name, rule));
    }
    check_shape(name, &a.dims, a.len())?;
    let dims = a
        .dims
        .iter()
        .map(|&d| i32::try_from(d))
        .collect::<Result<Vec<_>, _>>();
    let dims = dims.map_err(|_| MatError::unwritable(name, "a dimension exceeds 2^31-1"))?;
    let data_len = mi_size(a.data.storage().0)
        .unwrap_or(8)
        .saturating_mul(a.len());
    // Flags, dims and name elements plus padding must fit the u32 byte count too.
    let overhead = 64 + name.len() + 4 * dims.len();
    if data_len.saturating_add(overhead) > u32::MAX as usize {
        let reason = format!("{data_len} bytes exceed the 4 GiB MAT v5 limit");
        return Err(MatError::unwritable(name, reason));
    }
    Ok((dims, data_len))
}

/// Builds a complete miMATRIX element (tag included) for one variable.
fn matrix_element(name: &str, a: &MatArray) -> Result<Vec<u8>, MatError> {
    let (dims, data_len) = validate(name, a)?;
    let mut out = Vec::with_capacity(data_len + 128);
    out.extend_from_slice(&[0; 8]); // tag, filled in below
    push_elem(&mut out, MI_UINT32, 8, |o| {
        o.extend_from_slice(&a.class.code().to_le_bytes());
        o.extend_from_slice(&[0; 4]);
    });
    push_elem(&mut out, MI_INT32, 4 * dims.len(), |o| {
        dims.iter()
            .for_each(|d| o.extend_from_slice(&d.to_le_bytes()))
    });
    let name_bytes = name.as_bytes();
    push_elem(&mut out, MI_INT8, name.len(), |o| {
        o.extend_from_slice(name_bytes)
    });
    let ty = a.data.storage().0;
    push_elem(&mut out, ty, data_len, |o| a.data.push_le_bytes(o));
    let size = u32::try_from(out.len() - 8).unwrap_or(u32::MAX);
    out[..4].copy_from_slice(&MI_MATRIX.to_le_bytes());
    out[4..8].copy_from_slice(&size.to_le_bytes());
    Ok(out)
}

/// Writes a little-endian MAT v5 file scipy and MATLAB load: a fixed 128-byte header,
/// then each variable as a zlib miCOMPRESSED miMATRIX when `compress`, else plain.
/// Output is byte-identical for identical input (no timestamps). Every variable is
/// checked before anything is written, so a bad one leaves `w` untouched.
pub fn write_mat<W: Write>(
    mut w: W,
    vars: &[(&str, &MatArray)],
    compress: bool,
) -> Result<(), MatError> {
    for (i, (name, a)) in vars.iter().enumerate() {
        if vars[..i].iter().any(|(other, _)| other == name) {
            return Err(MatError::unwritable(name, "duplicate variable name"));
        }
        validate(name, a)?;
    }
    let mut header = [b' '; HEADER_LEN as usize];
    header[..HEADER_TEXT.len()].copy_from_slice(HEADER_TEXT);
    header[116..124].fill(0); // no subsystem data
    header[124..126].copy_from_slice(&0x0100u16.to_le_bytes());
    header[126..].copy_from_slice(b"IM");
    w.write_all(&header)?;
    for (name, a) in vars {
        let element = matrix_element(name, a)?;
        if compress {
            let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
            z.write_all(&element)?;
            let packed = z.finish()?;
            let len = u32::try_from(packed.len())
                .map_err(|_| MatError::unwritable(name, "compressed size exceeds 4 GiB"))?;
            w.write_all(&MI_COMPRESSED.to_le_bytes())?;
            w.write_all(&len.to_le_bytes())?;
            w.write_all(&packed)?;
        } else {
            w.write_all(&element)?;
        }
    }
    w.flush()?;
    Ok(())
}
