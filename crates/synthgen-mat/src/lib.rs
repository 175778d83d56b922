//! MATLAB Level 5 MAT-files (what `save -v6`/`-v7` and `scipy.io.savemat` write) for
//! numeric arrays, e.g. YCB-Video `NNNNNN-meta.mat`.
//!
//! The reader parses untrusted input: every declared size is checked against the bytes
//! that actually exist before anything is allocated, so bad files give `Err`, never a
//! panic or a huge allocation. v7.3 (HDF5) files are refused with an explanatory error.

const MI_INT8: u32 = 1;
const MI_UINT8: u32 = 2;
const MI_INT16: u32 = 3;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_SINGLE: u32 = 7;
const MI_DOUBLE: u32 = 9;
const MI_INT64: u32 = 12;
const MI_UINT64: u32 = 13;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const MI_UTF8: u32 = 16;

const HEADER_LEN: u64 = 128;
const HEADER_TEXT: &[u8] = b"MATLAB 5.0 MAT-file, Platform: synthgen, Created by: synthgen";
/// Whole variables are inflated into memory; beyond this a file is more likely hostile.
const MAX_INFLATED: u64 = 1 << 30;
/// Deflate cannot beat ~1032:1, so a larger declared inflated size cannot be honest.
const MAX_DEFLATE_RATIO: u64 = 1032;
/// Inflated bytes tried first for flags, dims and name, so unwanted variables stay cheap.
const PEEK: u64 = 256;
const ARRAY_COMPLEX: u32 = 0x0800;

/// MATLAB array class (what MATLAB calls the variable's type).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MatClass {
    /// `double` (mxDOUBLE_CLASS, 6).
    Double,
    /// `single` (mxSINGLE_CLASS, 7).
    Single,
    /// `int8` (8).
    Int8,
    /// `uint8` (9); also MATLAB `logical`, which is stored as uint8.
    UInt8,
    /// `int16` (10).
    Int16,
    /// `uint16` (11).
    UInt16,
    /// `int32` (12).
    Int32,
    /// `uint32` (13).
    UInt32,
    /// `int64` (14).
    Int64,
    /// `uint64` (15).
    UInt64,
}

impl MatClass {
    const ALL: [MatClass; 10] = [
        MatClass::Double,
        MatClass::Single,
        MatClass::Int8,
        MatClass::UInt8,
        MatClass::Int16,
        MatClass::UInt16,
        MatClass::Int32,
        MatClass::UInt32,
        MatClass::Int64,
        MatClass::UInt64,
    ];

    /// The mxCLASS code stored in the array flags (6..=15, in declaration order).
    fn code(self) -> u32 {
        6 + self as u32
    }

    fn from_code(code: u32) -> Option<MatClass> {
        Self::ALL.into_iter().find(|c| c.code() == code)
    }
}

/// Stored numeric values, column-major (MATLAB order: first dimension fastest).
#[derive(Debug, Clone, PartialEq)]
pub enum MatData {
    /// miDOUBLE storage.
    F64(Vec<f64>),
    /// miSINGLE storage.
    F32(Vec<f32>),
    /// miINT8 storage.
    I8(Vec<i8>),
    /// miUINT8 storage.
    U8(Vec<u8>),
    /// miINT16 storage.
    I16(Vec<i16>),
    /// miUINT16 storage.
    U16(Vec<u16>),
    /// miINT32 storage.
    I32(Vec<i32>),
    /// miUINT32 storage.
    U32(Vec<u32>),
    /// miINT64 storage.
    I64(Vec<i64>),
    /// miUINT64 storage.
    U64(Vec<u64>),
}

/// Applies one expression to the vector inside whichever variant `$data` is.
macro_rules! each_variant {
    ($data:expr, $v:ident => $body:expr) => {
        match $data {
            MatData::F64($v) => $body,
            MatData::F32($v) => $body,
            MatData::I8($v) => $body,
            MatData::U8($v) => $body,
            MatData::I16($v) => $body,
            MatData::U16($v) => $body,
            MatData::I32($v) => $body,
            MatData::U32($v) => $body,
            MatData::I64($v) => $body,
            MatData::U64($v) => $body,
        }
    };
}

/// Lossy by design for 64-bit integers above 2^53; MATLAB's `double()` behaves the same.
trait AsF64: Copy {
    fn as_f64(self) -> f64;
}
macro_rules! impl_as_f64 {
    ($($t:ty),*) => { $(impl AsF64 for $t { fn as_f64(self) -> f64 { self as f64 } })* };
}
impl_as_f64!(f32, i8, u8, i16, u16, i32, u32, i64, u64);
impl AsF64 for f64 {
    fn as_f64(self) -> f64 {
        self
    }
}

impl MatData {
    /// Number of stored values.
    pub fn len(&self) -> usize {
        each_variant!(self, v => v.len())
    }

    /// True when no values are stored.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Value at a column-major linear index as f64.
    pub fn get_f64(&self, i: usize) -> Option<f64> {
        each_variant!(self, v => v.get(i).map(|x| x.as_f64()))
    }

    /// The mi storage type and the class MATLAB gives an array stored that way.
    fn storage(&self) -> (u32, MatClass) {
        match self {
            MatData::F64(_) => (MI_DOUBLE, MatClass::Double),
            MatData::F32(_) => (MI_SINGLE, MatClass::Single),
            MatData::I8(_) => (MI_INT8, MatClass::Int8),
            MatData::U8(_) => (MI_UINT8, MatClass::UInt8),
            MatData::I16(_) => (MI_INT16, MatClass::Int16),
            MatData::U16(_) => (MI_UINT16, MatClass::UInt16),
            MatData::I32(_) => (MI_INT32, MatClass::Int32),
            MatData::U32(_) => (MI_UINT32, MatClass::UInt32),
            MatData::I64(_) => (MI_INT64, MatClass::Int64),
            MatData::U64(_) => (MI_UINT64, MatClass::UInt64),
        }
    }

    fn push_le_bytes(&self, out: &mut Vec<u8>) {
        each_variant!(self, v => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())))
    }
}

/// Size in bytes of one value of a numeric mi type; None for non-numeric types.
fn mi_size(ty: u32) -> Option<usize> {
    match ty {
        MI_INT8 | MI_UINT8 => Some(1),
        MI_INT16 | MI_UINT16 => Some(2),
        MI_INT32 | MI_UINT32 | MI_SINGLE => Some(4),
        MI_DOUBLE | MI_INT64 | MI_UINT64 => Some(8),
        _ => None,
    }
}

/// Decodes whole values of primitive `$t` from `$bytes` in the file's byte order.
macro_rules! decode_vec {
    ($bytes:expr, $be:expr, $t:ty) => {{
        const N: usize = std::mem::size_of::<$t>();
        $bytes
            .chunks_exact(N)
            .map(|c| {
                let mut a = [0u8; N];
                a.copy_from_slice(c);
                if $be {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            })
            .collect()
    }};
}

fn decode(ty: u32, b: &[u8], be: bool) -> Option<MatData> {
    Some(match ty {
        MI_INT8 => MatData::I8(b.iter().map(|&x| i8::from_ne_bytes([x])).collect()),
        MI_UINT8 => MatData::U8(b.to_vec()),
        MI_INT16 => MatData::I16(decode_vec!(b, be, i16)),
        MI_UINT16 => MatData::U16(decode_vec!(b, be, u16)),
        MI_INT32 => MatData::I32(decode_vec!(b, be, i32)),
        MI_UINT32 => MatData::U32(decode_vec!(b, be, u32)),
        MI_SINGLE => MatData::F32(decode_vec!(b, be, f32)),
        MI_DOUBLE => MatData::F64(decode_vec!(b, be, f64)),
        MI_INT64 => MatData::I64(decode_vec!(b, be, i64)),
        MI_UINT64 => MatData::U64(decode_vec!(b, be, u64)),
        _ => return None,
    })
}

/// A numeric MATLAB variable: shape, class and values as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct MatArray {
    /// Dimensions, at least two (MATLAB has no 1-D arrays).
    pub dims: Vec<usize>,
    /// What MATLAB reports as the type; may differ from the storage in `data`.
    pub class: MatClass,
    /// Values in the type they were stored with (scipy's `loadmat` dtype).
    pub data: MatData,
}

impl MatArray {
    /// Checks that `dims` (at least two) multiply to the number of values.
    pub fn new(dims: Vec<usize>, class: MatClass, data: MatData) -> Result<MatArray, MatError> {
        check_shape("", &dims, data.len())?;
        Ok(MatArray { dims, class, data })
    }

    /// A class-double array with the given storage, as MATLAB narrows e.g. `cls_indexes`
    /// to uint8 on disk while still loading it as double.
    pub fn double(dims: Vec<usize>, data: MatData) -> Result<MatArray, MatError> {
        MatArray::new(dims, MatClass::Double, data)
    }

    /// An array whose class matches its storage (F32 -> Single, I16 -> Int16, ...).
    pub fn native(dims: Vec<usize>, data: MatData) -> Result<MatArray, MatError> {
        let class = data.storage().1;
        MatArray::new(dims, class, data)
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// True for arrays with a zero dimension.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Every value as f64 (column-major).
    pub fn to_f64(&self) -> Vec<f64> {
        each_variant!(&self.data, v => v.iter().map(|x| x.as_f64()).collect())
    }

    /// Value at a multi-index (column-major), None when out of range.
    pub fn get_f64(&self, index: &[usize]) -> Option<f64> {
        if index.len() != self.dims.len() {
            return None;
        }
        let (mut linear, mut stride) = (0usize, 1usize);
        for (&i, &d) in index.iter().zip(&self.dims) {
            if i >= d {
                return None;
            }
            linear = linear.checked_add(i.checked_mul(stride)?)?;
            stride = stride.saturating_mul(d);
        }
        self.data.get_f64(linear)
    }
}

/// Errors from reading or writing MAT-files; messages omit the path, which callers add.
#[derive(Debug, thiserror::Error)]
pub enum MatError {
    /// The underlying reader or writer failed.
    #[error("i/o error: {0}")]
    Io(#[from] std::io::Error),
    /// Neither a "MATLAB ..." header text nor a valid endian indicator.
    #[error("not a MAT-file: no 'MATLAB 5.0 MAT-file' header")]
    NotMatFile,
    /// v7.3 files are HDF5 containers, a different format altogether.
    #[error(
        "MAT-file v7.3 (HDF5) is not supported: save it with -v7 (MATLAB) or scipy.io.savemat"
    )]
    V73,
    /// A header version other than 0x0100 (v5) or 0x0200 (v7.3).
    #[error("unsupported MAT-file version 0x{0:04x}")]
    UnsupportedVersion(u16),
    /// The file ends inside its 128-byte header.
    #[error("truncated: {0}-byte file is shorter than the 128-byte MAT-file header")]
    TruncatedHeader(u64),
    /// An element declares more bytes than remain.
    #[error("truncated: element at byte {offset} needs {need} bytes, {left} left")]
    Truncated {
        /// Offset of the element tag.
        offset: u64,
        /// Bytes the tag declares, tag included.
        need: u64,
        /// Bytes available from the tag on.
        left: u64,
    },
    /// A miCOMPRESSED element failed to inflate or inflated to something invalid.
    #[error("corrupt compressed element at byte {offset}: {reason}")]
    Corrupt {
        /// Offset of the miCOMPRESSED tag in the file.
        offset: u64,
        /// The zlib error or what was wrong with the inflated data.
        reason: String,
    },
    /// An element whose contents contradict the format.
    #[error("malformed element at byte {offset}: {reason}")]
    Malformed {
        /// Offset of the offending element (inside inflated data for compressed ones).
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// Dimensions that do not multiply to the number of values.
    #[error("{}{len} values for dims {dims}", var_prefix(.name))]
    Shape {
        /// Variable name, empty when not known yet.
        name: String,
        /// Number of values stored.
        len: usize,
        /// Dimensions as MATLAB prints them, e.g. "3x4x3".
        dims: String,
    },
    /// A variable the writer cannot represent (bad name, too large, duplicate).
    #[error("variable {name}: {reason}")]
    Unwritable {
        /// Variable name.
        name: String,
        /// Why it cannot be written.
        reason: String,
    },
}

impl MatError {
    fn truncated(offset: u64, need: u64, left: u64) -> MatError {
        MatError::Truncated { offset, need, left }
    }

    fn malformed(offset: u64, reason: impl Into<String>) -> MatError {
        let reason = reason.into();
        MatError::Malformed { offset, reason }
    }

    fn corrupt(offset: u64, reason: impl Into<String>) -> MatError {
        let reason = reason.into();
        MatError::Corrupt { offset, reason }
    }

    fn unwritable(name: &str, reason: impl Into<String>) -> MatError {
        let (name, reason) = (name.to_string(), reason.into());
        MatError::Unwritable { name, reason }
    }
}

fn var_prefix(name: &str) -> String {
    if name.is_empty() {
        String::new()
    } else {
        format!("variable {name}: ")
    }
}

fn check_shape(name: &str, dims: &[usize], len: usize) -> Result<(), MatError> {
    let product = dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    if dims.len() < 2 || product != Some(len) {
        let dims = dims
            .iter()
            .map(|d| d.to_string())
            .collect::<Vec<_>>()
            .join("x");
        return Err(MatError::Shape {
            name: name.to_string(),
            len,
            dims,
        });
    }
    Ok(())
}

fn word(b: [u8; 4], be: bool) -> u32 {
    if be {
        u32::from_be_bytes(b)
    } else {
        u32::from_le_bytes(b)
    }
}

fn word_at(buf: &[u8], at: usize, be: bool) -> Option<u32> {
    let b = buf.get(at..at.checked_add(4)?)?;
    Some(word([b[0], b[1], b[2], b[3]], be))
}

// After the macros above, which the submodules use.
mod read;
mod write;

pub use read::read_mat;
pub use write::write_mat;

#[cfg(test)]
mod tests;
