#![allow(clippy::unwrap_used, clippy::expect_used)]

use super::*;
use flate2::{write::ZlibEncoder, Compression};
use proptest::prelude::*;
use std::collections::BTreeMap;
use std::io::Cursor;
use std::io::Write;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

fn write_vec(vars: &[(&str, &MatArray)], compress: bool) -> Vec<u8> {
    let mut out = Vec::new();
    write_mat(&mut out, vars, compress).unwrap();
    out
}

fn read_vec(bytes: &[u8], wanted: Option<&[&str]>) -> Result<BTreeMap<String, MatArray>, MatError> {
    read_mat(Cursor::new(bytes), wanted)
}

/// One array of every storage type with `n` values, extremes included where they fit.
fn samples(n: usize) -> Vec<MatData> {
    let ints: Vec<i64> = (0..n as i64).map(|i| i * 7919 - 40).collect();
    let mut all = vec![
        MatData::F64(ints.iter().map(|&i| i as f64 * 0.37).collect()),
        MatData::F32(ints.iter().map(|&i| i as f32 * -0.25).collect()),
        MatData::I8(ints.iter().map(|&i| i as i8).collect()),
        MatData::U8(ints.iter().map(|&i| i as u8).collect()),
        MatData::I16(ints.iter().map(|&i| i as i16).collect()),
        MatData::U16(ints.iter().map(|&i| i as u16).collect()),
        MatData::I32(ints.iter().map(|&i| i as i32 * 4099).collect()),
        MatData::U32(
            ints.iter()
                .map(|&i| (i as u32).wrapping_mul(4099))
                .collect(),
        ),
        MatData::I64(ints.iter().map(|&i| i << 40).collect()),
        MatData::U64(ints.iter().map(|&i| (i as u64) << 40).collect()),
    ];
    if n >= 2 {
        if let MatData::I64(v) = &mut all[8] {
            v[0] = i64::MIN;
            v[1] = i64::MAX;
        }
        if let MatData::F64(v) = &mut all[0] {
            v[0] = f64::MIN_POSITIVE;
            v[1] = f64::INFINITY;
        }
    }
    all
}

/// A file or folder of `../shared/data/ycbv_real/data` (the tests that use it are ignored
/// without the shared data).
fn shared_meta(rel: &str) -> PathBuf {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/ycbv_real/data")
        .join(rel);
    assert!(path.exists(), "{} is absent", path.display());
    path
}

fn python(script: &str, args: &[&std::path::Path]) {
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "python failed:\n{text}");
}

/// Hand-built elements, so byte orders and shapes our writer never emits can be tested.
fn raw_elem(out: &mut Vec<u8>, be: bool, ty: u32, data: &[u8]) {
    let w = |x: u32| if be { x.to_be_bytes() } else { x.to_le_bytes() };
    if (1..=4).contains(&data.len()) {
        out.extend_from_slice(&w((data.len() as u32) << 16 | ty));
    } else {
        out.extend_from_slice(&w(ty));
        out.extend_from_slice(&w(data.len() as u32));
    }
    out.extend_from_slice(data);
    out.resize(out.len().div_ceil(8) * 8, 0);
}

fn raw_matrix(be: bool, flags: u32, dims: &[i32], name: &str, ty: u32, data: &[u8]) -> Vec<u8> {
    let w = |x: u32| if be { x.to_be_bytes() } else { x.to_le_bytes() };
    let mut body = Vec::new();
    raw_elem(&mut body, be, MI_UINT32, &[w(flags), [0; 4]].concat());
    let dims: Vec<u8> = dims.iter().flat_map(|&d| w(d as u32)).collect();
    raw_elem(&mut body, be, MI_INT32, &dims);
    raw_elem(&mut body, be, MI_INT8, name.as_bytes());
    raw_elem(&mut body, be, ty, data);
    let mut out = Vec::new();
    raw_elem(&mut out, be, MI_MATRIX, &body);
    out
}

fn raw_file(be: bool, elements: &[Vec<u8>]) -> Vec<u8> {
    let mut out = vec![b' '; 116];
    out[..20].copy_from_slice(b"MATLAB 5.0 MAT-file ");
    out.extend_from_slice(&[0; 8]);
    out.extend_from_slice(if be {
        &[1, 0, b'M', b'I']
    } else {
        &[0, 1, b'I', b'M']
    });
    elements.iter().for_each(|e| out.extend_from_slice(e));
    out
}

fn zlib(bytes: &[u8]) -> Vec<u8> {
    let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
    z.write_all(bytes).unwrap();
    z.finish().unwrap()
}

fn compressed(be: bool, element: &[u8]) -> Vec<u8> {
    let packed = zlib(element);
    let w = |x: u32| if be { x.to_be_bytes() } else { x.to_le_bytes() };
    [&w(MI_COMPRESSED)[..], &w(packed.len() as u32), &packed].concat()
}

/// Big-endian file: int16 2x2, a small-format uint8 1x2, a compressed single 1x3.
fn big_endian_file() -> Vec<u8> {
    let i16s: Vec<u8> = [1i16, -2, 300, -400]
        .iter()
        .flat_map(|x| x.to_be_bytes())
        .collect();
    let f32s: Vec<u8> = [0.5f32, -1.0, 3.25]
        .iter()
        .flat_map(|x| x.to_be_bytes())
        .collect();
    raw_file(
        true,
        &[
            raw_matrix(true, 10, &[2, 2], "x", MI_INT16, &i16s),
            raw_matrix(true, 9, &[1, 2], "tiny", MI_UINT8, &[7, 9]),
            compressed(true, &raw_matrix(true, 7, &[1, 3], "z", MI_SINGLE, &f32s)),
        ],
    )
}

#[test]
fn round_trip_every_variant_and_shape() {
    for compress in [false, true] {
        for dims in [
            vec![3, 4, 2],
            vec![0, 3],
            vec![0, 0],
            vec![1, 1],
            vec![2, 1],
            vec![1, 4],
        ] {
            let n = dims.iter().product();
            for (k, data) in samples(n).into_iter().enumerate() {
                let name = format!("v{k}");
                let a = MatArray::native(dims.clone(), data).unwrap();
                let bytes = write_vec(&[(&name, &a)], compress);
                let back = read_vec(&bytes, None).unwrap();
                assert_eq!(back.len(), 1);
                assert_eq!(back[&name], a, "{dims:?} compress={compress}");
                assert_eq!(write_vec(&[(&name, &back[&name])], compress), bytes);
            }
        }
    }
}

#[test]
fn small_element_format_is_used_for_tiny_data_and_names() {
    let a = MatArray::native(vec![1, 1], MatData::U16(vec![513])).unwrap();
    let bytes = write_vec(&[("ab", &a)], false);
    // tag 8 + flags 16 + dims 16 + name 8 (small) + data 8 (small)
    assert_eq!(bytes.len(), 128 + 56);
    assert_eq!(&bytes[128 + 40..128 + 44], &[1, 0, 2, 0]); // miINT8, 2 bytes
    assert_eq!(&bytes[128 + 48..128 + 54], &[4, 0, 2, 0, 1, 2]); // miUINT16, 2 bytes
    assert_eq!(read_vec(&bytes, None).unwrap()["ab"], a);
}

#[test]
fn names_of_every_length_and_class_differing_from_storage() {
    let names: Vec<String> = (1..=40)
        .map(|n| format!("n{}", "_x".repeat(n)).chars().take(n).collect())
        .collect();
    let arrays: Vec<MatArray> = (0..40)
        .map(|i| MatArray::double(vec![2, 1], MatData::U8(vec![i, 255 - i])).unwrap())
        .collect();
    let vars: Vec<(&str, &MatArray)> = names.iter().map(|s| s.as_str()).zip(&arrays).collect();
    for compress in [false, true] {
        let back = read_vec(&write_vec(&vars, compress), None).unwrap();
        assert_eq!(back.len(), 40);
        for (name, a) in &vars {
            assert_eq!(&back[*name], *a);
            assert_eq!(back[*name].class, MatClass::Double);
        }
    }
}

#[test]
fn output_is_deterministic_with_fixed_header() {
    let a = MatArray::native(vec![3, 4, 2], samples(24).remove(1)).unwrap();
    let first = write_vec(&[("a", &a)], true);
    assert_eq!(first, write_vec(&[("a", &a)], true));
    assert!(first.starts_with(HEADER_TEXT));
    assert!(first[HEADER_TEXT.len()..116].iter().all(|&b| b == b' '));
    assert_eq!(
        &first[116..128],
        &[0, 0, 0, 0, 0, 0, 0, 0, 0, 1, b'I', b'M']
    );
}

#[test]
fn accessors_follow_column_major_order() {
    let a = MatArray::native(vec![2, 3], MatData::I32(vec![0, 1, 2, 3, 4, 5])).unwrap();
    assert_eq!(a.get_f64(&[1, 0]), Some(1.0));
    assert_eq!(a.get_f64(&[0, 2]), Some(4.0));
    assert_eq!(a.get_f64(&[2, 0]), None);
    assert_eq!(a.get_f64(&[0]), None);
    assert_eq!(a.to_f64(), vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
    assert_eq!((a.len(), a.is_empty()), (6, false));
    let err = MatArray::double(vec![3, 4, 3], MatData::F64(vec![0.0; 12])).unwrap_err();
    assert_eq!(err.to_string(), "12 values for dims 3x4x3");
    assert!(MatArray::double(vec![4], MatData::F64(vec![0.0; 4])).is_err());
    assert!(MatArray::double(vec![usize::MAX, 2], MatData::F64(vec![])).is_err());
}

#[test]
fn writer_rejects_bad_variables_before_writing() {
    let ok = MatArray::double(vec![1, 1], MatData::F64(vec![1.0])).unwrap();
    let bad_shape = MatArray {
        dims: vec![2, 2],
        class: MatClass::Double,
        data: MatData::F64(vec![1.0]),
    };
    let long = "a".repeat(64);
    for name in ["", "1a", "_x", "a-b", "é", long.as_str()] {
        let mut out = Vec::new();
        assert!(
            write_mat(&mut out, &[("fine", &ok), (name, &ok)], true).is_err(),
            "{name:?}"
        );
        assert!(out.is_empty());
    }
    let mut out = Vec::new();
    let err = write_mat(&mut out, &[("poses", &bad_shape)], false).unwrap_err();
    assert_eq!(err.to_string(), "variable poses: 1 values for dims 2x2");
    let err = write_mat(&mut out, &[("a", &ok), ("a", &ok)], false).unwrap_err();
    assert_eq!(err.to_string(), "variable a: duplicate variable name");
    assert!(out.is_empty());
}

#[test]
fn big_endian_files_are_read() {
    let m = read_vec(&big_endian_file(), None).unwrap();
    assert_eq!(m["x"].data, MatData::I16(vec![1, -2, 300, -400]));
    assert_eq!(
        (m["x"].class, m["x"].dims.clone()),
        (MatClass::Int16, vec![2, 2])
    );
    assert_eq!(m["tiny"].data, MatData::U8(vec![7, 9]));
    assert_eq!(m["z"].data, MatData::F32(vec![0.5, -1.0, 3.25]));
    assert_eq!(m["z"].class, MatClass::Single);
}

#[test]
fn last_duplicate_wins_and_non_numeric_shadows() {
    let one = MatArray::double(vec![1, 1], MatData::F64(vec![1.0])).unwrap();
    let two = MatArray::double(vec![1, 1], MatData::F64(vec![2.0])).unwrap();
    let mut bytes = write_vec(&[("x", &one), ("y", &one)], true);
    bytes.extend_from_slice(&write_vec(&[("x", &two)], false)[128..]);
    let m = read_vec(&bytes, None).unwrap();
    assert_eq!((m["x"].to_f64(), m["y"].to_f64()), (vec![2.0], vec![1.0]));
    // A later char array named y hides the earlier numeric y, as in MATLAB.
    bytes.extend_from_slice(&raw_matrix(false, 4, &[1, 2], "y", MI_UINT16, b"h\0i\0"));
    assert_eq!(
        read_vec(&bytes, None).unwrap().keys().collect::<Vec<_>>(),
        ["x"]
    );
    // Complex variables, MATLAB objects (no dims element) and the nameless subsystem
    // array are skipped without error.
    let cplx = raw_matrix(false, 6 | ARRAY_COMPLEX, &[1, 1], "c", MI_DOUBLE, &[0; 8]);
    let mut object = Vec::new();
    raw_elem(&mut object, false, MI_UINT32, &[17, 0, 0, 0, 0, 0, 0, 0]);
    for text in ["s", "MCOS", "string"] {
        raw_elem(&mut object, false, MI_INT8, text.as_bytes());
    }
    object.extend_from_slice(&raw_matrix(false, 13, &[1, 2], "", MI_UINT32, &[1; 8]));
    let mut object_element = Vec::new();
    raw_elem(&mut object_element, false, MI_MATRIX, &object);
    let subsystem = raw_matrix(false, 9, &[1, 8], "", MI_UINT8, &[3; 8]);
    let z = compressed(false, &object_element);
    let file = raw_file(false, &[cplx, object_element, z, subsystem]);
    assert!(read_vec(&file, None).unwrap().is_empty());
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn real_ycbv_meta_file() {
    let path = shared_meta("0000/000001-meta.mat");
    let t = Instant::now();
    let m = read_mat(std::fs::File::open(&path).unwrap(), None).unwrap();
    let all = t.elapsed();
    let keys: Vec<&str> = m.keys().map(|k| k.as_str()).collect();
    let expected = [
        "center",
        "cls_indexes",
        "factor_depth",
        "intrinsic_matrix",
        "poses",
        "rotation_translation_matrix",
        "vertmap",
    ];
    assert_eq!(keys, expected);
    let cls = &m["cls_indexes"];
    assert_eq!(
        (cls.dims.clone(), cls.class),
        (vec![3, 1], MatClass::Double)
    );
    assert_eq!(cls.data, MatData::U8(vec![8, 14, 21]));
    assert_eq!(m["factor_depth"].data, MatData::U16(vec![10000]));
    let k = &m["intrinsic_matrix"];
    assert_eq!(
        (k.get_f64(&[0, 0]), k.get_f64(&[0, 2])),
        (Some(1066.778), Some(312.9869))
    );
    let poses = &m["poses"];
    assert_eq!(poses.dims, vec![3, 4, 3]);
    assert_eq!(poses.get_f64(&[0, 0, 0]), Some(0.023388461238133155));
    assert_eq!(poses.get_f64(&[2, 3, 0]), Some(0.5926409962060182));
    assert_eq!(
        (m["vertmap"].dims.clone(), m["vertmap"].class),
        (vec![480, 640, 3], MatClass::Single)
    );
    assert!(matches!(m["vertmap"].data, MatData::F32(_)));
    assert_eq!(m["center"].dims, vec![3, 2]);

    let t = Instant::now();
    let only = read_mat(std::fs::File::open(&path).unwrap(), Some(&["poses"])).unwrap();
    let one = t.elapsed();
    println!("000001-meta.mat: all variables {all:?}, only poses {one:?}");
    assert_eq!(only.keys().collect::<Vec<_>>(), ["poses"]);
    assert_eq!(&only["poses"], poses);

    // Every shipped meta file parses with the same variables.
    for dir in ["0000", "0001", "0002"] {
        let dir = shared_meta(dir);
        for entry in std::fs::read_dir(dir).unwrap() {
            let p = entry.unwrap().path();
            if p.to_string_lossy().ends_with("-meta.mat") {
                let m = read_mat(std::fs::File::open(&p).unwrap(), None).unwrap();
                assert_eq!(m.keys().collect::<Vec<_>>(), expected, "{}", p.display());
                assert_eq!(
                    m["poses"].dims[2],
                    m["cls_indexes"].dims[0],
                    "{}",
                    p.display()
                );
            }
        }
    }
}

const CHECK_OURS: &str = r#"
import sys, numpy as np, scipy.io as sio
ours, real, rewritten, be = [sio.loadmat(p) for p in sys.argv[1:5]]
keys = lambda m: sorted(k for k in m if not k.startswith('__'))
assert keys(ours) == keys(real) == keys(rewritten), (keys(ours), keys(real), keys(rewritten))
for k in keys(real):
    got, want = ours[k], real[k]
    assert (got.shape, got.dtype) == (want.shape, want.dtype), (k, got.shape, got.dtype, want.shape, want.dtype)
    assert rewritten[k].dtype == want.dtype and np.array_equal(rewritten[k], want), k
assert ours['cls_indexes'].ravel().tolist() == [8, 14, 21]
assert ours['factor_depth'][0, 0] == 10000
assert ours['intrinsic_matrix'][0, 0] == 1066.778 and ours['intrinsic_matrix'][0, 2] == 312.9869
assert np.array_equal(ours['poses'].ravel(order='F'), np.arange(36) * 0.125)
assert np.array_equal(ours['vertmap'].ravel(order='F'), (np.arange(480 * 640 * 3) % 97).astype(np.float32))
assert ours['center'][2, 1] == 6.0 and ours['rotation_translation_matrix'][1, 3] == 10.0
for k, dtype, values in [('x', np.int16, [[1, 300], [-2, -400]]), ('tiny', np.uint8, [[7, 9]]), ('z', np.float32, [[0.5, -1.0, 3.25]])]:
    assert be[k].dtype.newbyteorder('=') == dtype and be[k].tolist() == values, (k, be[k])
"#;

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
#[cfg_attr(
    not(has_scipy),
    ignore = "needs python3 with scipy: pip install scipy (probed when the crate was built)"
)]
fn scipy_loads_what_we_write() {
    let real = shared_meta("0000/000001-meta.mat");
    let f64s = |n: usize, scale: f64| MatData::F64((0..n).map(|i| i as f64 * scale).collect());
    let cls = MatArray::double(vec![3, 1], MatData::U8(vec![8, 14, 21])).unwrap();
    let depth = MatArray::double(vec![1, 1], MatData::U16(vec![10000])).unwrap();
    let k = [
        1066.778, 0.0, 0.0, 0.0, 1067.487, 0.0, 312.9869, 241.3109, 1.0,
    ];
    let k = MatArray::double(vec![3, 3], MatData::F64(k.to_vec())).unwrap();
    let rt = MatArray::double(vec![3, 4], f64s(12, 1.0)).unwrap();
    let vert = (0..480 * 640 * 3).map(|i| (i % 97) as f32).collect();
    let vert = MatArray::native(vec![480, 640, 3], MatData::F32(vert)).unwrap();
    let poses = MatArray::double(vec![3, 4, 3], f64s(36, 0.125)).unwrap();
    let center = MatArray::double(vec![3, 2], f64s(6, 1.2)).unwrap();
    let vars = [
        ("cls_indexes", &cls),
        ("factor_depth", &depth),
        ("intrinsic_matrix", &k),
        ("rotation_translation_matrix", &rt),
        ("vertmap", &vert),
        ("poses", &poses),
        ("center", &center),
    ];
    let dir = tempfile::tempdir().unwrap();
    let ours = dir.path().join("ours.mat");
    write_mat(std::fs::File::create(&ours).unwrap(), &vars, true).unwrap();
    // Re-encoding the real file must preserve every value and dtype.
    let m = read_mat(std::fs::File::open(&real).unwrap(), None).unwrap();
    let rewritten = dir.path().join("rewritten.mat");
    let vars: Vec<(&str, &MatArray)> = m.iter().map(|(k, v)| (k.as_str(), v)).collect();
    write_mat(std::fs::File::create(&rewritten).unwrap(), &vars, false).unwrap();
    let be = dir.path().join("be.mat");
    std::fs::write(&be, big_endian_file()).unwrap();
    python(CHECK_OURS, &[&ours, &real, &rewritten, &be]);
}

const WRITE_SCIPY: &str = r#"
import sys, numpy as np, scipy.io as sio
d = {
    'i16': np.array([[1, -2, 3], [-32768, 32767, 0]], dtype=np.int16),
    'f32': (np.arange(24, dtype=np.float32) / 8).reshape(2, 3, 4),
    'scalar': 2.5,
    'u64': np.array([[2**63 + 5]], dtype=np.uint64),
    'flag': np.array([True, False, True]),
    'empty': np.zeros((0, 3)),
    'text': 'hello',
    'st': {'a': 1.0, 'b': 'x'},
    'cells': np.array([1, 'a'], dtype=object),
    'cplx': np.array([1 + 2j]),
}
sio.savemat(sys.argv[1], d, do_compression=True)
sio.savemat(sys.argv[2], d, do_compression=False)
"#;

#[test]
#[cfg_attr(
    not(has_scipy),
    ignore = "needs python3 with scipy: pip install scipy (probed when the crate was built)"
)]
fn we_load_what_scipy_writes() {
    let dir = tempfile::tempdir().unwrap();
    let (zipped, plain) = (dir.path().join("z.mat"), dir.path().join("p.mat"));
    python(WRITE_SCIPY, &[&zipped, &plain]);
    for path in [zipped, plain] {
        let m = read_mat(std::fs::File::open(&path).unwrap(), None).unwrap();
        let keys: Vec<&str> = m.keys().map(|k| k.as_str()).collect();
        assert_eq!(
            keys,
            ["empty", "f32", "flag", "i16", "scalar", "u64"],
            "{}",
            path.display()
        );
        assert_eq!(
            m["i16"].data,
            MatData::I16(vec![1, -32768, -2, 32767, 3, 0])
        );
        assert_eq!(
            (m["i16"].dims.clone(), m["i16"].class),
            (vec![2, 3], MatClass::Int16)
        );
        let f32 = &m["f32"];
        assert_eq!(
            (f32.dims.clone(), f32.class),
            (vec![2, 3, 4], MatClass::Single)
        );
        for (i, j, k) in [(0, 0, 0), (1, 2, 3), (1, 0, 2), (0, 1, 1)] {
            let want = (i * 12 + j * 4 + k) as f64 / 8.0;
            assert_eq!(f32.get_f64(&[i, j, k]), Some(want));
        }
        assert_eq!(
            (m["scalar"].dims.clone(), m["scalar"].to_f64()),
            (vec![1, 1], vec![2.5])
        );
        assert_eq!(m["u64"].data, MatData::U64(vec![(1 << 63) + 5]));
        assert_eq!(
            (m["flag"].class, m["flag"].dims.clone()),
            (MatClass::UInt8, vec![1, 3])
        );
        assert_eq!(m["flag"].data, MatData::U8(vec![1, 0, 1]));
        assert_eq!((m["empty"].dims.clone(), m["empty"].len()), (vec![0, 3], 0));
    }
}

fn fuzz_seed(compress: bool) -> Vec<u8> {
    let a = MatArray::double(vec![2, 3], MatData::F64(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0])).unwrap();
    let b = MatArray::double(vec![1, 3], MatData::U8(vec![8, 14, 21])).unwrap();
    let c = MatArray::native(vec![0, 2], MatData::F32(vec![])).unwrap();
    let d = MatArray::native(vec![2, 2], MatData::I16(vec![-1, 2, -3, 4])).unwrap();
    write_vec(
        &[("a", &a), ("bb", &b), ("c", &c), ("long_name", &d)],
        compress,
    )
}

#[test]
fn every_prefix_and_byte_flip_is_handled() {
    let t = Instant::now();
    let mut reads = 0;
    for compress in [false, true] {
        let file = fuzz_seed(compress);
        assert_eq!(read_vec(&file, None).unwrap().len(), 4);
        for len in 0..file.len() {
            if let Ok(m) = read_vec(&file[..len], None) {
                assert!(m.len() < 4, "prefix {len} of {} read whole", file.len());
            }
            reads += 1;
        }
        for at in 0..file.len() {
            for mask in [0x01, 0x10, 0x80, 0xff] {
                let mut bad = file.clone();
                bad[at] ^= mask;
                let _ = read_vec(&bad, None);
                let _ = read_vec(&bad, Some(&["bb"]));
                reads += 2;
            }
        }
    }
    println!("{reads} corrupted reads in {:?}", t.elapsed());
}

#[test]
fn header_errors() {
    let mut v73 =
        b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan 1 HDF5 schema 1.00 ."
            .to_vec();
    v73.resize(512, b' ');
    let err = read_vec(&v73, None).unwrap_err();
    assert!(matches!(err, MatError::V73));
    assert_eq!(
        err.to_string(),
        "MAT-file v7.3 (HDF5) is not supported: save it with -v7 (MATLAB) or scipy.io.savemat"
    );
    let noise: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    let err = read_vec(&noise, None).unwrap_err();
    assert_eq!(
        err.to_string(),
        "not a MAT-file: no 'MATLAB 5.0 MAT-file' header"
    );
    assert!(matches!(
        read_vec(b"", None),
        Err(MatError::TruncatedHeader(0))
    ));
    let mut v2 = fuzz_seed(false);
    v2[124..126].copy_from_slice(&[0, 2]);
    assert!(matches!(read_vec(&v2, None), Err(MatError::V73)));
    v2[124..126].copy_from_slice(&[0, 7]);
    assert!(matches!(
        read_vec(&v2, None),
        Err(MatError::UnsupportedVersion(0x0700))
    ));
}

#[test]
fn huge_declared_sizes_are_refused_without_allocating() {
    let mut lying = raw_file(false, &[]);
    lying.extend_from_slice(&MI_MATRIX.to_le_bytes());
    lying.extend_from_slice(&0xffff_fff0u32.to_le_bytes());
    lying.extend_from_slice(&[0; 40]);
    let err = read_vec(&lying, None).unwrap_err();
    assert_eq!(
        err.to_string(),
        "truncated: element at byte 128 needs 4294967288 bytes, 48 left"
    );

    let tag = [MI_MATRIX.to_le_bytes(), 0x7fff_fff0u32.to_le_bytes()].concat();
    let bomb = raw_file(false, &[compressed(false, &tag)]);
    let err = read_vec(&bomb, None).unwrap_err();
    assert!(
        matches!(err, MatError::Corrupt { offset: 128, .. }),
        "{err}"
    );

    let huge = raw_matrix(
        false,
        6,
        &[i32::MAX, i32::MAX, i32::MAX],
        "h",
        MI_DOUBLE,
        &[],
    );
    let err = read_vec(&raw_file(false, &[huge]), None).unwrap_err();
    assert_eq!(
        err.to_string(),
        "variable h: 0 values for dims 2147483647x2147483647x2147483647"
    );

    let wrong = raw_matrix(false, 6, &[3, 4, 3], "poses", MI_DOUBLE, &[0; 96]);
    let err = read_vec(&raw_file(false, &[compressed(false, &wrong)]), None).unwrap_err();
    assert_eq!(err.to_string(), "variable poses: 12 values for dims 3x4x3");

    let mut sum = fuzz_seed(true);
    *sum.last_mut().unwrap() ^= 1; // the zlib adler32 of the last variable
    let err = read_vec(&sum, None).unwrap_err();
    assert!(matches!(err, MatError::Corrupt { .. }), "{err}");

    let mut cut = fuzz_seed(true);
    let n = cut.len();
    cut[n - 20..].fill(0); // damage the zlib stream of the last variable
    let err = read_vec(&cut, None).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("corrupt compressed element at byte "),
        "{err}"
    );
}

fn data_strategy() -> impl Strategy<Value = (Vec<usize>, MatData)> {
    (
        prop::collection::vec(0usize..4, 2..=4),
        0usize..10,
        any::<u64>(),
    )
        .prop_map(|(dims, kind, seed)| {
            let n = dims.iter().product::<usize>();
            let bits: Vec<u64> = (0..n as u64)
                .map(|i| seed.rotate_left(i as u32 * 7) ^ i.wrapping_mul(0x9e37_79b9))
                .collect();
            let data = match kind {
                0 => MatData::F64(bits.iter().map(|&b| f64::from_bits(b)).collect()),
                1 => MatData::F32(bits.iter().map(|&b| f32::from_bits(b as u32)).collect()),
                2 => MatData::I8(bits.iter().map(|&b| b as i8).collect()),
                3 => MatData::U8(bits.iter().map(|&b| b as u8).collect()),
                4 => MatData::I16(bits.iter().map(|&b| b as i16).collect()),
                5 => MatData::U16(bits.iter().map(|&b| b as u16).collect()),
                6 => MatData::I32(bits.iter().map(|&b| b as i32).collect()),
                7 => MatData::U32(bits.iter().map(|&b| b as u32).collect()),
                8 => MatData::I64(bits.iter().map(|&b| b as i64).collect()),
                _ => MatData::U64(bits),
            };
            (dims, data)
        })
}

proptest! {
    #[test]
    fn prop_round_trip((dims, data) in data_strategy(), compress: bool, class in 0usize..10) {
        let a = MatArray::new(dims, MatClass::ALL[class], data).unwrap();
        let bytes = write_vec(&[("p", &a)], compress);
        let back = read_vec(&bytes, None).unwrap();
        // Byte equality of a re-write compares floats by bits, NaNs included.
        prop_assert_eq!(&back["p"].dims, &a.dims);
        prop_assert_eq!(back["p"].class, a.class);
        prop_assert_eq!(write_vec(&[("p", &back["p"])], compress), bytes);
    }

    #[test]
    fn prop_random_bytes_are_not_mat_files(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        if !bytes.is_empty() && !bytes.starts_with(b"M") {
            prop_assert!(matches!(read_vec(&bytes, None), Err(MatError::NotMatFile)));
        }
    }

    #[test]
    fn prop_random_body_never_panics(body in prop::collection::vec(any::<u8>(), 0..600), be: bool) {
        let mut bytes = raw_file(be, &[]);
        bytes.extend_from_slice(&body);
        let _ = read_vec(&bytes, None);
    }
}
