//! The same inputs and options give byte-identical output files on the same
//! adapter: the bake (direct light and bounces) and every file export writes.

use crate::common;
use std::collections::BTreeMap;
use std::path::Path;

fn bake(out: &Path, format: &str) -> BTreeMap<String, Vec<u8>> {
    let output = common::tiny_bake(&common::fixture("everything.glb"), out, &["--format", format]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    std::fs::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap() != "report.json") // holds timings
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect()
}

#[test]
fn baking_twice_gives_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    for format in ["glb", "gltf"] {
        let first = bake(&dir.path().join(format!("{format}-1")), format);
        let second = bake(&dir.path().join(format!("{format}-2")), format);
        assert_eq!(first.keys().collect::<Vec<_>>(), second.keys().collect::<Vec<_>>());
        assert!(first.contains_key("everything.lightmap0.exr") && first.contains_key(&format!("everything.{format}")));
        for (name, bytes) in &first {
            assert!(*bytes == second[name], "{name} differs between two identical bakes");
            eprintln!("{name}: {} bytes, identical", bytes.len());
        }
    }
}
