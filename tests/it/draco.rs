//! Draco-compressed meshes (KHR_draco_mesh_compression), as glTF-Transform
//! writes them with Google's Draco library: bake decodes them on load to the
//! values Google's own decoder gives, bakes them as it bakes that decoder's
//! plain output, and writes a plain file the validator accepts. The encoder
//! and the independent decoder are `pipeline/draco.mjs` (npm packages pinned
//! in pipeline/package-lock.json, installed by pipeline/setup.sh); without
//! them these tests fail, they never skip.

use crate::common;

use std::path::{Path, PathBuf};

use bake::asset::{SourceAsset, accessor};
use bake::report::Report;

/// Writes fixture `name` Draco-compressed with encoder `flags`, and Google's
/// decoding of that file; returns (compressed, decoded).
fn compress(name: &str, dir: &Path, tag: &str, flags: &[&str]) -> (PathBuf, PathBuf) {
    let input = common::repo(&format!("fixtures/{name}.glb"));
    let (compressed, decoded) = (dir.join(format!("{tag}.glb")), dir.join(format!("{tag}.decoded.glb")));
    let mut args = vec!["encode".as_ref(), input.as_os_str(), compressed.as_os_str()];
    args.extend(flags.iter().map(std::ffi::OsStr::new));
    common::node("pipeline/draco.mjs", &args);
    common::node("pipeline/draco.mjs", &["decode".as_ref(), compressed.as_os_str(), decoded.as_os_str()]);
    (compressed, decoded)
}

/// How many primitives of `file` carry the Draco extension.
fn compressed_primitives(file: &Path) -> usize {
    let bytes = std::fs::read(file).unwrap();
    let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&glb.json).unwrap();
    let primitives = json["meshes"].as_array().unwrap().iter().flat_map(|m| m["primitives"].as_array().unwrap());
    primitives.filter(|p| p.pointer("/extensions/KHR_draco_mesh_compression").is_some()).count()
}

/// Every attribute and index list of `ours` against `theirs`, primitive by
/// primitive: equal to the bit, but for skin weights, which bake scales to
/// sum to 1 (the encoder's quantization leaves them a step off).
fn assert_same_meshes(what: &str, ours: &SourceAsset, theirs: &SourceAsset) {
    let mut compared = 0;
    for (a, b) in ours.document.meshes().zip(theirs.document.meshes()) {
        for (pa, pb) in a.primitives().zip(b.primitives()) {
            let at = format!("{what}: mesh {} primitive {}", a.index(), pa.index());
            assert_eq!(pa.attributes().count(), pb.attributes().count(), "{at}");
            for (semantic, accessor_a) in pa.attributes() {
                let accessor_b = pb.get(&semantic).unwrap_or_else(|| panic!("{at}: {semantic:?} missing"));
                let va = accessor::read_floats(ours, &accessor_a).unwrap();
                let vb = accessor::read_floats(theirs, &accessor_b).unwrap();
                assert_eq!(va.len(), vb.len(), "{at}: {semantic:?}");
                if let gltf::Semantic::Weights(_) = semantic {
                    let worst = va.iter().zip(&vb).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max);
                    assert!(worst < 1e-3, "{at}: weights differ by {worst}");
                    for point in va.chunks_exact(4) {
                        assert!((point.iter().sum::<f32>() - 1.0).abs() < 1e-6, "{at}: weights {point:?}");
                    }
                } else if let Some(i) = (0..va.len()).find(|&i| va[i].to_bits() != vb[i].to_bits()) {
                    panic!("{at}: {semantic:?} value {i} is {} here, {} by Google's decoder", va[i], vb[i]);
                }
                compared += 1;
            }
            let indices = |asset, p: &gltf::Primitive| p.indices().map(|i| accessor::read_indices(asset, &i).unwrap());
            assert_eq!(indices(ours, &pa), indices(theirs, &pb), "{at}: indices");
        }
    }
    eprintln!("{what}: {compared} attributes alike");
    assert!(compared > 0, "{what}: nothing compared");
}

#[test]
fn draco_meshes_decode_to_what_googles_decoder_gives() {
    let dir = tempfile::tempdir().unwrap();
    // Both codecs (edgebreaker, sequential), coarse and fine quantization,
    // and the everything fixture's skin weights and joints, 8-bit colours,
    // tangents, second UV set and uncompressed points primitive.
    let cases: &[(&str, &str, &[&str])] = &[
        ("corner", "edgebreaker", &[]),
        ("corner", "sequential", &["--method", "sequential"]),
        ("corner", "coarse", &["--position-bits", "8", "--normal-bits", "4", "--texcoord-bits", "6", "--speed", "10"]),
        ("corner", "fine", &["--position-bits", "16", "--normal-bits", "16", "--texcoord-bits", "16", "--speed", "0"]),
        ("sphere_on_ground", "sphere", &[]),
        ("everything", "everything", &[]),
        ("everything", "everything-sequential", &["--method", "sequential", "--generic-bits", "8"]),
    ];
    for (fixture, tag, flags) in cases {
        let (compressed, decoded) = compress(fixture, dir.path(), tag, flags);
        assert!(compressed_primitives(&compressed) >= 2, "{tag}: the encoder compressed too little to test");
        let ours = SourceAsset::load(&compressed).unwrap_or_else(|e| panic!("{tag}: {e:#}"));
        assert!(ours.json.get("extensionsRequired").is_none(), "{tag}: {}", ours.json["extensionsRequired"]);
        let theirs = SourceAsset::load(&decoded).unwrap();
        assert_same_meshes(tag, &ours, &theirs);
    }
}

/// Bakes `input` at 64² under the sun-and-sky fixture; returns its report.
fn bake(input: &Path, out: &Path) -> Report {
    common::bake_file(input, out, &["--max-atlas-size", "64", "--lights", "64", "--max-shots", "128", "-q"])
}

#[test]
fn a_draco_file_bakes_as_its_decoded_form_does_into_a_valid_plain_file() {
    let dir = tempfile::tempdir().unwrap();
    for fixture in ["corner", "everything"] {
        let (compressed, decoded) = compress(fixture, dir.path(), fixture, &[]);
        let (out_compressed, out_decoded) = (dir.path().join(format!("{fixture}-c")), dir.path().join(fixture));
        let ours = bake(&compressed, &out_compressed);
        let theirs = bake(&decoded, &out_decoded);
        let stats = |report: &Report| -> Vec<(usize, [f64; 3])> {
            report.scenes[0].energy.iter().map(|e| (e.stats.texels, e.stats.mean_lightmap)).collect()
        };
        assert!(stats(&ours).len() >= 3);
        assert_eq!(stats(&ours), stats(&theirs), "{fixture}: each primitive's texels and mean");

        let baked = out_compressed.join(format!("{fixture}.glb"));
        common::node("pipeline/validate.mjs", &[baked.as_os_str()]);
        let output = SourceAsset::load(&baked).unwrap();
        let listed = |key: &str| output.json.get(key).map(ToString::to_string).unwrap_or_default();
        for key in ["extensionsUsed", "extensionsRequired"] {
            assert!(!listed(key).contains("KHR_draco_mesh_compression"), "{fixture}: {key} {}", listed(key));
        }
    }
}

#[test]
fn corrupt_draco_bitstreams_are_errors_not_crashes() {
    // 1,500 copies of a compressed corner with bytes of one primitive's Draco
    // bitstream changed (header bytes in half the cases, where the counts
    // are): each must load, or fail with an error, never panic.
    let dir = tempfile::tempdir().unwrap();
    let (compressed, _) = compress("corner", dir.path(), "corner", &[]);
    let bytes = std::fs::read(&compressed).unwrap();
    let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&glb.json).unwrap();
    let bin = glb.bin.unwrap().into_owned();
    let torus = json["meshes"].as_array().unwrap().iter().position(|m| m["name"] == "torus").expect("a torus");
    let view = json["meshes"][torus]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"]
        .as_u64()
        .unwrap() as usize;
    let view = &json["bufferViews"][view];
    let (start, length) = (view["byteOffset"].as_u64().unwrap_or(0) as usize, view["byteLength"].as_u64().unwrap());
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut random = move |below: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % below as u64) as usize
    };
    let (mut loaded, mut refused) = (0, 0);
    for case in 0..1500 {
        let mut corrupt = bin.clone();
        let span = if case % 2 == 0 { 40 } else { length as usize };
        for _ in 0..1 + random(4) {
            let at = start + random(span);
            corrupt[at] = if case % 3 == 0 { random(256) as u8 } else { corrupt[at] ^ 1 << random(8) };
        }
        let file = bake::export::glb::encode(&glb.json, &corrupt);
        let outcome = std::panic::catch_unwind(|| {
            SourceAsset::from_bytes(Path::new("corrupt.glb"), &file, None).and_then(bake::import::from_asset)
        });
        match outcome {
            Ok(Ok(_)) => loaded += 1,
            Ok(Err(_)) => refused += 1,
            Err(_) => panic!("case {case}: decoding panicked"),
        }
    }
    eprintln!("{loaded} loaded, {refused} refused");
    assert!(refused > 0, "no corruption was noticed");
}
