//! Python's own json module reads what we write and writes it back byte for byte, in
//! bop_toolkit's `save_json` layout. Ignored where the build script found no python3.

use std::process::Command;

use synthgen_formats::bop::BopWriter;

use crate::common::{options, write_frames};

const SCRIPT: &str = r#"
import json, pathlib, sys

def bop_layout(content):
    # bop_toolkit's save_json: one sorted top-level entry per line.
    items = sorted(content.items(), key=lambda kv: kv[0])
    lines = ['  "{}": {}'.format(k, json.dumps(v, sort_keys=True)) for k, v in items]
    return '{\n' + ',\n'.join(lines) + ('\n' if lines else '') + '}'

def int_keys(d):
    return {int(k) if k.lstrip('-').isdigit() else k: v for k, v in d.items()}

root = pathlib.Path(sys.argv[1])
n = 0
for path in sorted(root.rglob('*.json')):
    text = path.read_text()
    data = json.loads(text, object_hook=int_keys)
    assert bop_layout(data) == text, 'layout differs: %s' % path
    if path.name == 'scene_gt.json':
        for im, gts in data.items():
            for g in gts:
                assert len(g['cam_R_m2c']) == 9 and len(g['cam_t_m2c']) == 3, path
                assert isinstance(g['obj_id'], int), path
                assert all(isinstance(v, float) for v in g['cam_R_m2c']), path
    if path.name == 'scene_gt_info.json':
        for im, infos in data.items():
            for i in infos:
                assert isinstance(i['px_count_all'], int) and isinstance(i['visib_fract'], float)
    n += 1
print(n)
"#;

#[test]
#[cfg_attr(
    not(has_python3),
    ignore = "needs python3 on PATH (probed when the crate was built)"
)]
fn python_json_reads_and_rewrites_identically() {
    let dir = tempfile::tempdir().unwrap();
    let writer = BopWriter::create(dir.path(), options(2)).unwrap();
    writer.write_camera_json().unwrap();
    write_frames(&writer, &[0, 1, 2, 3, 4]);
    writer.finish().unwrap();
    let out = Command::new("python3")
        .arg("-c")
        .arg(SCRIPT)
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "python failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    // camera.json + 3 scene folders x 3 files.
    assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), "10");
}
