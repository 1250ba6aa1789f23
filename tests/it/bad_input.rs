//! Bad input through the real `bake` binary, each case in a fresh folder:
//! every malformed scene or environment ends with exit code 2, one line on
//! stderr naming the file and the problem, and nothing left behind (no
//! output folder, no staging folder, no partial file). The malformed files
//! are made here from the fixture GLBs, never committed.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::{self, fixture};
use bake::environment::{EnvironmentMap, ExrPrecision};
use bake::report::Report;
use serde_json::{Value, json};

/// The fixture `sphere_on_ground.glb` as (JSON, BIN chunk).
fn parts() -> (Value, Vec<u8>) {
    let bytes = std::fs::read(fixture("sphere_on_ground.glb")).unwrap();
    let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
    (serde_json::from_slice(&glb.json).unwrap(), glb.bin.unwrap().into_owned())
}

fn glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    bake::export::glb::encode(&serde_json::to_vec(json).unwrap(), bin)
}

/// Byte offset in the BIN chunk of element `element` of accessor `accessor`.
fn element_offset(json: &Value, accessor: usize, element: usize) -> usize {
    let a = &json["accessors"][accessor];
    let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    let size = match a["type"].as_str().unwrap() {
        "VEC3" => 12,
        "VEC2" => 8,
        _ => 4,
    };
    view["byteOffset"].as_u64().unwrap_or(0) as usize + a["byteOffset"].as_u64().unwrap_or(0) as usize + element * size
}

/// A fresh folder to run `bake` in.
struct Case {
    dir: tempfile::TempDir,
}

impl Case {
    fn new() -> Case {
        Case { dir: tempfile::tempdir().unwrap() }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn write(&self, name: &str, bytes: &[u8]) -> &Case {
        std::fs::write(self.path(name), bytes).unwrap();
        self
    }

    fn entries(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(self.dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    /// Runs `bake ARGS -o out -q` with a small atlas and light budget unless ARGS set them.
    fn run(&self, args: &[&str]) -> Output {
        let mut command = common::bake_command();
        command.current_dir(self.dir.path()).args(args).args(["-o", "out", "-q"]);
        for default in [["--max-atlas-size", "32"], ["--lights", "16"], ["--max-shots", "64"]] {
            if !args.contains(&default[0]) {
                command.args(default);
            }
        }
        finish(command)
    }

    /// Runs `bake INPUT --env sky_constant.hdr` on a file written here.
    fn bake(&self, input: &str) -> Output {
        let env = fixture("sky_constant.hdr");
        self.run(&[input, "--env", env.to_str().unwrap()])
    }

    /// The run failed with exit code 2, printing one line that names `file` and
    /// contains `problem`, and left the folder as it was before the run.
    fn refused(&self, args: &[&str], file: &str, problem: &str) -> String {
        let before = self.entries();
        let output = if args.len() == 1 { self.bake(args[0]) } else { self.run(args) };
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert_eq!(output.status.code(), Some(2), "stderr: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "one line only: {stderr}");
        let line = stderr.lines().next().unwrap();
        assert!(line.starts_with("bake: error: "), "{line}");
        assert!(line.contains(file), "the error does not name '{file}': {line}");
        assert!(line.contains(problem), "the error does not say '{problem}': {line}");
        assert_eq!(self.entries(), before, "the run left files behind");
        assert!(!self.path("out").exists());
        eprintln!("{line}");
        line.to_string()
    }
}

/// Runs `command` to its end, failing the test if that takes more than a
/// minute: a run that blocks on its input must not block the suite.
fn finish(mut command: Command) -> Output {
    use std::process::Stdio;
    let mut child = command.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("bake runs");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            let output = child.wait_with_output().unwrap();
            panic!("bake still running after 60 s: {}", String::from_utf8_lossy(&output.stderr));
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn a_truncated_glb_is_refused() {
    let bytes = std::fs::read(fixture("sphere_on_ground.glb")).unwrap();
    let case = Case::new();
    case.write("half.glb", &bytes[..bytes.len() / 2]);
    case.refused(&["half.glb"], "half.glb", "truncated .glb: the header declares");
    // Cut inside the header, and inside the JSON chunk with a length field fixed to match.
    case.write("header.glb", &bytes[..10]);
    case.refused(&["header.glb"], "header.glb", "shorter than the 12-byte header");
    let mut cut = bytes[..100].to_vec();
    cut[8..12].copy_from_slice(&100u32.to_le_bytes());
    case.write("chunk.glb", &cut);
    case.refused(&["chunk.glb"], "chunk.glb", "the JSON chunk at byte 12 declares");
}

#[test]
fn a_glb_with_a_header_length_below_its_header_is_refused() {
    // Regression: gltf's own reader computes `length - 12` and overflows
    // (a panic in debug builds) when the declared length is under 12.
    let mut bytes = std::fs::read(fixture("sphere_on_ground.glb")).unwrap();
    bytes[8..12].copy_from_slice(&4u32.to_le_bytes());
    let case = Case::new();
    case.write("short.glb", &bytes);
    case.refused(&["short.glb"], "short.glb", "no JSON chunk");
}

#[test]
fn wrong_magic_and_version_are_refused() {
    let bytes = std::fs::read(fixture("sphere_on_ground.glb")).unwrap();
    let case = Case::new();
    let mut magic = bytes.clone();
    magic[..4].copy_from_slice(b"glTX");
    case.write("magic.glb", &magic);
    case.refused(&["magic.glb"], "magic.glb", "not a glTF file");
    let mut version = bytes;
    version[4] = 1;
    case.write("v1.glb", &version);
    case.refused(&["v1.glb"], "v1.glb", "unsupported .glb version 1");
}

#[test]
fn bad_json_is_refused_with_its_position() {
    let (json, bin) = parts();
    let mut text = serde_json::to_vec(&json).unwrap();
    let at = text.iter().position(|&c| c == b':').unwrap();
    text[at] = b';';
    let case = Case::new();
    case.write("json.glb", &bake::export::glb::encode(&text, &bin));
    case.refused(&["json.glb"], "json.glb", "invalid glTF JSON: expected `:` at line 1");
    // Valid JSON that is not glTF: a required field missing.
    let mut json = json;
    json["accessors"][0].as_object_mut().unwrap().remove("componentType");
    case.write("schema.glb", &glb(&json, &bin));
    case.refused(&["schema.glb"], "schema.glb", "invalid glTF JSON: missing field `componentType`");
}

#[test]
fn an_accessor_past_its_buffer_view_is_refused() {
    let (mut json, bin) = parts();
    json["accessors"][0]["count"] = json!(26); // the view holds 25 positions
    let case = Case::new();
    case.write("count.glb", &glb(&json, &bin));
    case.refused(&["count.glb"], "count.glb", "accessor 0: 26 elements of 12 bytes");
    let (mut json, bin) = parts();
    json["accessors"][0]["byteOffset"] = json!(4);
    case.write("offset.glb", &glb(&json, &bin));
    case.refused(&["offset.glb"], "offset.glb", "run past the end of bufferView 0");
    let (mut json, bin) = parts();
    json["bufferViews"][0]["byteOffset"] = json!(bin.len() - 100);
    case.write("view.glb", &glb(&json, &bin));
    case.refused(&["view.glb"], "view.glb", "bufferView 0 (300 bytes at");
}

#[test]
fn a_triangle_list_cut_short_bakes_its_whole_triangles_with_a_notice() {
    // Not a multiple of 3 (the spec asks for one): engines draw the whole
    // triangles; so does bake, and it says so.
    let (mut json, bin) = parts();
    let indices = json["meshes"][0]["primitives"][0]["indices"].as_u64().unwrap() as usize;
    let count = json["accessors"][indices]["count"].as_u64().unwrap();
    json["accessors"][indices]["count"] = json!(count - 2);
    let case = Case::new();
    case.write("cut.glb", &glb(&json, &bin));
    let output = case.bake("cut.glb");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let notices = &report(&case).scenes[0].notices;
    let cut = format!(
        "primitive 0 draws {} vertices, not a multiple of 3: {} triangles are baked and the last vertex is left out",
        count - 2,
        count / 3 - 1
    );
    assert!(notices.iter().any(|n| n.contains(&cut)), "{notices:?}");
}

#[test]
fn indices_past_the_vertex_count_are_refused() {
    let (json, mut bin) = parts();
    let at = element_offset(&json, 3, 5);
    bin[at..at + 4].copy_from_slice(&25u32.to_le_bytes()); // 25 vertices: 0..=24
    let case = Case::new();
    case.write("indices.glb", &glb(&json, &bin));
    case.refused(&["indices.glb"], "indices.glb", "index 25 is past the vertex count 25");
}

#[test]
fn non_finite_positions_are_refused() {
    let case = Case::new();
    for (name, value) in [("nan.glb", f32::NAN), ("inf.glb", f32::INFINITY), ("neg.glb", f32::NEG_INFINITY)] {
        let (json, mut bin) = parts();
        let at = element_offset(&json, 4, 7) + 4; // the sphere's 8th vertex, y
        bin[at..at + 4].copy_from_slice(&value.to_le_bytes());
        case.write(name, &glb(&json, &bin));
        case.refused(&[name], name, "mesh 1 'sphere' on node 1 'sphere', primitive 0: POSITION 7 is not finite");
    }
    // Finite positions that a node transform takes past f32's range.
    let (mut json, bin) = parts();
    json["nodes"][1]["scale"] = json!([1e38, 1e38, 1e38]);
    json["nodes"][1]["translation"] = json!([3e38, 0.0, 0.0]);
    case.write("overflow.glb", &glb(&json, &bin));
    case.refused(&["overflow.glb"], "overflow.glb", "the scene spans 4e38 m along x, more than the 1e7 m");
}

#[test]
fn huge_declared_counts_are_refused_before_allocating() {
    // Each declaration would need tens of GiB if believed; the process would
    // die or swap instead of printing the line checked here.
    let case = Case::new();
    // Within the triangle and vertex budgets, which count the declared
    // indices and vertices before anything is read.
    let env = fixture("sky_constant.hdr");
    let within = |name| [name, "--env", env.to_str().unwrap(), "--max-triangles", "2000000000"];
    let (mut json, bin) = parts();
    json["accessors"][4]["count"] = json!(u32::MAX);
    case.write("count.glb", &glb(&json, &bin));
    case.refused(&within("count.glb"), "count.glb", "accessor 4: 4294967295 elements of 12 bytes");
    let (mut json, bin) = parts();
    json["accessors"][7]["count"] = json!(2_000_000_000u32);
    json["bufferViews"][7]["byteLength"] = json!(8_000_000_000u64);
    case.write("view.glb", &glb(&json, &bin));
    case.refused(&within("view.glb"), "view.glb", "bufferView 7 (8000000000 bytes at");
    let (mut json, bin) = parts();
    json["buffers"][0]["byteLength"] = json!(1u64 << 40);
    case.write("buffer.glb", &glb(&json, &bin));
    case.refused(&["buffer.glb"], "buffer.glb", "buffer 0 is truncated: 66880 bytes of the declared 1099511627776");
    // A sparse accessor with no buffer view is zeros plus its sparse values:
    // its count alone decides the size.
    let (mut json, bin) = parts();
    json["accessors"][4].as_object_mut().unwrap().remove("bufferView");
    json["accessors"][4]["count"] = json!(1_000_000_000u32);
    json["accessors"][4]["sparse"] = json!({
        "count": 1,
        "indices": { "bufferView": 3, "componentType": 5125 },
        "values": { "bufferView": 0 },
    });
    case.write("viewless.glb", &glb(&json, &bin));
    let problem = "accessor 4: 1000000000 elements of 12 bytes with no bufferView";
    case.refused(&within("viewless.glb"), "viewless.glb", problem);
}

#[test]
fn a_buffer_declared_shorter_than_its_views_is_refused() {
    // The bytes past the declared length are not the buffer's, though the
    // file holds them (66,880 bytes): the spec and its validator refuse a
    // view that reaches them.
    let case = Case::new();
    let (mut json, bin) = parts();
    json["buffers"][0]["byteLength"] = json!(66_000);
    case.write("short_buffer.glb", &glb(&json, &bin));
    case.refused(&["short_buffer.glb"], "short_buffer.glb", "runs past the end of buffer 0 (66000 bytes)");
}

/// The fixture as `NAME.gltf` with its buffer in the file `uri`.
fn gltf_with_buffer(case: &Case, name: &str, uri: &str) -> Vec<u8> {
    let (mut json, bin) = parts();
    json["buffers"][0]["uri"] = json!(uri);
    case.write(name, &serde_json::to_vec(&json).unwrap());
    bin
}

#[test]
fn a_missing_buffer_file_is_named() {
    let case = Case::new();
    gltf_with_buffer(&case, "scene.gltf", "scene%20data.bin");
    let line = case.refused(&["scene.gltf"], "scene.gltf", "buffer 0: cannot read");
    assert!(line.contains("scene data.bin") && line.contains("No such file"), "{line}");
    // Present but shorter than declared.
    let bin = gltf_with_buffer(&case, "short.gltf", "short.bin");
    case.write("short.bin", &bin[..1000]);
    case.refused(&["short.gltf"], "short.gltf", "buffer 0 is truncated: 1000 bytes of the declared 66880");
}

/// The fixture with its ground textured by image file `uri`.
fn glb_with_image(uri: &str) -> Vec<u8> {
    let (mut json, bin) = parts();
    json["images"] = json!([{ "uri": uri }]);
    json["textures"] = json!([{ "source": 0 }]);
    json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    glb(&json, &bin)
}

#[test]
fn a_missing_image_file_is_named_before_baking() {
    let case = Case::new();
    case.write("textured.glb", &glb_with_image("albedo.png"));
    let line = case.refused(&["textured.glb"], "textured.glb", "image 0: cannot read");
    assert!(line.contains("albedo.png") && line.contains("No such file"), "{line}");
    // A folder where the image should be.
    std::fs::create_dir(case.path("folder.png")).unwrap();
    case.write("folder.glb", &glb_with_image("folder.png"));
    case.refused(&["folder.glb"], "folder.glb", "image 0: 'folder.png' is not a file");
}

#[test]
fn uris_pointing_outside_the_input_folder_are_refused() {
    // The files exist, so only the policy can refuse them.
    let outer = tempfile::tempdir().unwrap();
    let (_, bin) = parts();
    std::fs::write(outer.path().join("secret.bin"), &bin).unwrap();
    let case = Case { dir: tempfile::tempdir_in(outer.path()).unwrap() };
    let absolute = outer.path().join("secret.bin");
    for (name, uri) in [
        ("up.gltf", "../secret.bin"),
        ("deep.gltf", "sub/../../secret.bin"),
        ("escaped.gltf", "%2E%2E/secret.bin"),
        ("absolute.gltf", absolute.to_str().unwrap()),
        ("remote.gltf", "https://example.com/secret.bin"),
    ] {
        gltf_with_buffer(&case, name, uri);
        case.refused(&[name], name, "buffer 0: refusing");
    }
    std::fs::write(outer.path().join("secret.png"), b"\x89PNG\r\n\x1a\n").unwrap();
    case.write("image.glb", &glb_with_image("../secret.png"));
    case.refused(
        &["image.glb"],
        "image.glb",
        "image 0: refusing '../secret.png': it points outside the asset's folder",
    );
}

#[test]
fn symlinks_resolving_outside_the_input_folder_are_refused() {
    // Each link names a file that exists and would bake: only the policy can refuse it.
    let outer = tempfile::tempdir().unwrap();
    let (_, bin) = parts();
    std::fs::write(outer.path().join("secret.bin"), &bin).unwrap();
    std::fs::write(outer.path().join("secret.png"), b"\x89PNG\r\n\x1a\n").unwrap();
    let case = Case { dir: tempfile::tempdir_in(outer.path()).unwrap() };
    let link = |target: &Path, name: &str| std::os::unix::fs::symlink(target, case.path(name)).unwrap();
    link(Path::new("../secret.bin"), "relative.bin");
    link(&outer.path().join("secret.bin"), "absolute.bin");
    link(outer.path(), "sub");
    link(Path::new("/etc/passwd"), "passwd.bin");
    for (name, uri) in
        [("relative.gltf", "relative.bin"), ("absolute.gltf", "absolute.bin"), ("sub.gltf", "sub/secret.bin")]
    {
        gltf_with_buffer(&case, name, uri);
        let line = case.refused(&[name], name, "buffer 0: refusing");
        assert!(line.contains("outside the asset's folder"), "{line}");
    }
    // A second buffer of the password file's length: its size must not show either.
    let (mut json, bin) = parts();
    case.write("scene.bin", &bin);
    json["buffers"][0]["uri"] = json!("scene.bin");
    let length = std::fs::metadata("/etc/passwd").unwrap().len();
    json["buffers"].as_array_mut().unwrap().push(json!({ "uri": "passwd.bin", "byteLength": length }));
    case.write("second.gltf", &serde_json::to_vec(&json).unwrap());
    let line = case.refused(&["second.gltf"], "second.gltf", "buffer 1: refusing 'passwd.bin'");
    assert!(!line.contains(&length.to_string()), "{line}");
    link(Path::new("../secret.png"), "albedo.png");
    case.write("image.glb", &glb_with_image("albedo.png"));
    case.refused(&["image.glb"], "image.glb", "image 0: refusing 'albedo.png': it points outside the asset's folder");
}

#[test]
fn symlinks_inside_the_input_folder_are_followed() {
    let case = Case::new();
    let bin = gltf_with_buffer(&case, "scene.gltf", "alias.bin");
    std::fs::create_dir(case.path("data")).unwrap();
    case.write("data/scene.bin", &bin);
    std::os::unix::fs::symlink("data/scene.bin", case.path("alias.bin")).unwrap();
    let output = case.bake("scene.gltf");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
}

/// A FIFO (nobody writes to it) at `name` in the case's folder.
fn mkfifo(case: &Case, name: &str) {
    let status = Command::new("mkfifo").arg(case.path(name)).status().expect("mkfifo runs");
    assert!(status.success());
}

#[test]
fn inputs_that_are_not_regular_files_are_refused() {
    let case = Case::new();
    let env = fixture("sky_constant.hdr");
    let env = env.to_str().unwrap();
    // Each role gets a FIFO (which blocks a reader forever) and a link to /dev/zero (which never ends).
    mkfifo(&case, "fifo.glb");
    std::os::unix::fs::symlink("/dev/zero", case.path("zero.glb")).unwrap();
    for name in ["fifo.glb", "zero.glb"] {
        case.refused(&[name, "--env", env], name, "not a regular file");
    }
    mkfifo(&case, "fifo.hdr");
    std::os::unix::fs::symlink("/dev/zero", case.path("zero.hdr")).unwrap();
    std::fs::copy(fixture("sphere_on_ground.glb"), case.path("scene.glb")).unwrap();
    for name in ["fifo.hdr", "zero.hdr"] {
        case.refused(&["scene.glb", "--env", name], name, "not a regular file");
    }
    mkfifo(&case, "fifo.bin");
    std::os::unix::fs::symlink("/dev/zero", case.path("zero.bin")).unwrap();
    // A file the asset names must lie in its folder, and /dev/zero does not.
    for (name, uri, problem) in [
        ("fifo.gltf", "fifo.bin", "buffer 0: cannot read 'fifo.bin': it is a FIFO (named pipe), not a regular file"),
        ("zero.gltf", "zero.bin", "buffer 0: refusing 'zero.bin': it points outside the asset's folder"),
    ] {
        gltf_with_buffer(&case, name, uri);
        case.refused(&[name], name, problem);
    }
    mkfifo(&case, "fifo.png");
    std::os::unix::fs::symlink("/dev/zero", case.path("zero.png")).unwrap();
    for (name, uri, problem) in [
        ("fifo_image.glb", "fifo.png", "image 0: 'fifo.png' is not a file"),
        ("zero_image.glb", "zero.png", "image 0: refusing 'zero.png'"),
    ] {
        case.write(name, &glb_with_image(uri));
        case.refused(&[name], name, problem);
    }
}

#[test]
fn unsupported_required_extensions_are_refused() {
    let case = Case::new();
    let (mut json, bin) = parts();
    json["extensionsUsed"] = json!(["EXT_unknown_thing"]);
    json["extensionsRequired"] = json!(["EXT_unknown_thing"]);
    case.write("ext.glb", &glb(&json, &bin));
    case.refused(&["ext.glb"], "ext.glb", "requires the extension EXT_unknown_thing, which bake does not support");
}

#[test]
fn corrupt_draco_compressed_data_is_refused_naming_the_buffer_view() {
    // sphere_on_ground's first primitive marked Draco-compressed, its
    // attributes' data dropped and its Draco mesh said to be in the view of
    // its indices, which holds no Draco bitstream.
    let (mut json, bin) = parts();
    let primitive = json["meshes"][0]["primitives"][0].clone();
    let view = json["accessors"][primitive["indices"].as_u64().unwrap() as usize]["bufferView"].clone();
    let mut ids = serde_json::Map::new();
    for (k, (name, accessor)) in primitive["attributes"].as_object().unwrap().iter().enumerate() {
        json["accessors"][accessor.as_u64().unwrap() as usize].as_object_mut().unwrap().remove("bufferView");
        ids.insert(name.clone(), json!(k));
    }
    json["meshes"][0]["primitives"][0]["extensions"] =
        json!({ "KHR_draco_mesh_compression": { "bufferView": view, "attributes": ids } });
    json["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    json["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    let case = Case::new();
    case.write("draco.glb", &glb(&json, &bin));
    let problem = format!("buffer view {view} is not a Draco mesh that decodes");
    let line = case.refused(&["draco.glb"], "draco.glb", &problem);
    assert!(line.contains("mesh 0 primitive 0 (KHR_draco_mesh_compression)"), "{line}");
}

#[test]
fn required_extensions_bake_reads_are_accepted() {
    // gltfpack marks KHR_mesh_quantization required; the gltf crate alone refuses it.
    // A KTX2 texture without a fallback image has no `source`, which the
    // gltf crate alone also refuses. This one holds only the KTX2
    // identifier: bake cannot decode it and says so.
    let case = Case::new();
    let (mut json, bin) = parts();
    let names = ["KHR_mesh_quantization", "KHR_materials_variants", "EXT_mesh_gpu_instancing", "KHR_texture_basisu"];
    json["extensionsUsed"] = json!(names);
    json["extensionsRequired"] = json!(names);
    json["images"] = json!([{ "uri": "data:image/ktx2;base64,q0tUWCAyMLsNChoK" }]);
    json["textures"] = json!([{ "extensions": { "KHR_texture_basisu": { "source": 0 } } }]);
    json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    case.write("required.glb", &glb(&json, &bin));
    let output = case.bake("required.glb");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let notices = &report(&case).scenes[0].notices;
    let undecodable = "image 0 could not be decoded (a KTX2 file of 12 bytes is shorter than its header)";
    assert!(notices.iter().any(|n| n.contains(undecodable)), "{notices:?}");

    // An AVIF-only texture (EXT_texture_avif) is carried the same way.
    json["extensionsUsed"] = json!(["EXT_texture_avif"]);
    json["extensionsRequired"] = json!(["EXT_texture_avif"]);
    json["textures"] = json!([{ "extensions": { "EXT_texture_avif": { "source": 0 } } }]);
    case.write("avif.glb", &glb(&json, &bin));
    let output = case.bake("avif.glb");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let notices = &report(&case).scenes[0].notices;
    assert!(notices.iter().any(|n| n.contains("only an extension's image (EXT_texture_avif)")), "{notices:?}");

    // One that names an image past the list is refused.
    json["textures"] = json!([{ "extensions": { "EXT_texture_avif": { "source": 3 } } }]);
    let case = Case::new();
    case.write("missing.glb", &glb(&json, &bin));
    case.refused(
        &["missing.glb"],
        "missing.glb",
        "textures[0].extensions.EXT_texture_avif.source is 3, but there are 1 images",
    );
}

/// An 8×8 JPEG whose frame header (SOF0) says it is `width`×`height`.
fn jpeg_declaring(width: u16, height: u16) -> Vec<u8> {
    let mut bytes = Vec::new();
    let image = image::RgbImage::from_pixel(8, 8, image::Rgb([200, 100, 50]));
    image::codecs::jpeg::JpegEncoder::new(&mut bytes).encode_image(&image).unwrap();
    let sof = bytes.windows(2).position(|w| w == [0xFF, 0xC0]).expect("a baseline frame header");
    // Marker, length (2), precision (1), then height and width, big-endian.
    bytes[sof + 5..sof + 7].copy_from_slice(&height.to_be_bytes());
    bytes[sof + 7..sof + 9].copy_from_slice(&width.to_be_bytes());
    bytes
}

#[test]
fn images_declaring_more_than_8192_squared_texels_are_baked_as_absent_before_decoding() {
    use base64::Engine as _;
    for (width, height, decoded) in [(9000, 9000, false), (65535, 1100, false), (64, 64, true)] {
        let case = Case::new();
        let (mut json, bin) = parts();
        let data = base64::engine::general_purpose::STANDARD.encode(jpeg_declaring(width, height));
        json["images"] = json!([{ "uri": format!("data:image/jpeg;base64,{data}") }]);
        json["textures"] = json!([{ "source": 0 }]);
        json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
        case.write("large.glb", &glb(&json, &bin));
        let output = case.bake("large.glb");
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let notices = &report(&case).scenes[0].notices;
        let refused =
            format!("image 0 could not be decoded (it is {width}×{height} texels, more than a 8192×8192 image");
        assert_eq!(notices.iter().any(|n| n.contains(&refused)), !decoded, "{notices:?}");
        // The one that fits decodes or fails on its data, not on its size.
        assert!(notices.iter().all(|n| !n.contains("the most bake decodes")) || !decoded, "{notices:?}");
    }
}

#[test]
fn gpu_instances_with_mismatched_attributes_are_refused_naming_the_node() {
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let mut scene = SceneBuilder::new();
    let cube = scene.mesh("box", &MeshData::cuboid([1.0; 3]), None);
    let instances = [Placement::default(), Placement::at(glam::Vec3::X * 2.0), Placement::at(glam::Vec3::X * 4.0)];
    scene.instanced_node("boxes", cube, Placement::default(), &instances);
    let bytes = scene.to_glb();
    let parsed = gltf::binary::Glb::from_slice(&bytes).unwrap();
    let (mut json, bin): (Value, Vec<u8>) =
        (serde_json::from_slice(&parsed.json).unwrap(), parsed.bin.unwrap().into_owned());
    let rotation = json["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["ROTATION"].clone();
    json["accessors"][rotation.as_u64().unwrap() as usize]["count"] = json!(2);
    let case = Case::new();
    case.write("boxes.glb", &glb(&json, &bin));
    case.refused(&["boxes.glb"], "boxes.glb", "node 0 'boxes': EXT_mesh_gpu_instancing: ROTATION has 2 entries");
}

#[test]
fn corrupt_meshopt_compressed_data_is_refused_naming_the_buffer_view() {
    // sphere_on_ground with its first POSITION view stored as gltfpack does:
    // meshopt-compressed bytes at the end of the BIN chunk, the view itself
    // in a fallback buffer with no data.
    let (mut json, mut bin) = parts();
    let accessor = json["meshes"][0]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap() as usize;
    let view = json["accessors"][accessor]["bufferView"].as_u64().unwrap() as usize;
    let (offset, length) =
        (element_offset(&json, accessor, 0), json["bufferViews"][view]["byteLength"].as_u64().unwrap());
    let positions: Vec<[u8; 12]> =
        bin[offset..offset + length as usize].chunks_exact(12).map(|c| c.try_into().unwrap()).collect();
    let encoded = meshopt::encode_vertex_buffer(&positions).unwrap();
    let at = bin.len();
    bin.extend_from_slice(&encoded);
    json["buffers"][0]["byteLength"] = json!(bin.len());
    let fallback = json!({ "byteLength": json["buffers"][0]["byteLength"], "extensions": {
        "EXT_meshopt_compression": { "fallback": true } } });
    json["buffers"].as_array_mut().unwrap().push(fallback);
    json["bufferViews"][view]["buffer"] = json!(1);
    json["bufferViews"][view]["extensions"] = json!({ "EXT_meshopt_compression": {
        "buffer": 0, "byteOffset": at, "byteLength": encoded.len(), "byteStride": 12,
        "count": positions.len(), "mode": "ATTRIBUTES" } });
    json["extensionsUsed"] = json!(["EXT_meshopt_compression"]);
    json["extensionsRequired"] = json!(["EXT_meshopt_compression"]);
    let case = Case::new();
    case.write("packed.glb", &glb(&json, &bin));
    let output = case.bake("packed.glb");
    assert!(output.status.success(), "the intact file bakes: {}", String::from_utf8_lossy(&output.stderr));

    // Cut short, the data cannot be decoded.
    json["bufferViews"][view]["extensions"]["EXT_meshopt_compression"]["byteLength"] = json!(encoded.len() / 2);
    let case = Case::new();
    case.write("corrupt.glb", &glb(&json, &bin));
    case.refused(
        &["corrupt.glb"],
        "corrupt.glb",
        &format!("buffer view {view}: the compressed vertex data is corrupt"),
    );
}

#[test]
fn a_bad_second_input_leaves_none_of_the_first_ones_outputs() {
    let case = Case::new();
    std::fs::create_dir(case.path("out")).unwrap();
    std::fs::write(case.path("out/keep.txt"), "previous").unwrap();
    std::fs::copy(fixture("sphere.glb"), case.path("good.glb")).unwrap();
    let (json, bin) = parts();
    let mut bytes = glb(&json, &bin);
    bytes.truncate(bytes.len() - 8);
    case.write("bad.glb", &bytes);
    let env = fixture("sky_constant.hdr");
    let output = case.run(&["good.glb", "bad.glb", "--env", env.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(stderr.trim().starts_with("bake: error: input 'bad.glb': truncated .glb"), "{stderr}");
    let left: Vec<_> = std::fs::read_dir(case.path("out")).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, ["keep.txt"], "the failed run left files in the output folder");
}

/// Every entry of `folder` with its bytes (a folder's as empty), in name order.
fn snapshot(folder: &Path) -> Vec<(String, Vec<u8>)> {
    let mut entries: Vec<(String, Vec<u8>)> = std::fs::read_dir(folder)
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            let bytes = if path.is_dir() { Vec::new() } else { std::fs::read(&path).unwrap() };
            (path.file_name().unwrap().to_string_lossy().into_owned(), bytes)
        })
        .collect();
    entries.sort();
    entries
}

#[test]
fn an_environment_map_named_as_an_output_is_never_replaced() {
    let case = Case::new();
    std::fs::create_dir(case.path("out")).unwrap();
    std::fs::copy(fixture("sphere.glb"), case.path("good.glb")).unwrap();
    std::fs::copy(fixture("sky_constant.exr"), case.path("out/good.lightmap0.exr")).unwrap();
    let before = snapshot(&case.path("out"));
    let output = case.run(&["good.glb", "--env", "out/good.lightmap0.exr"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("out/good.lightmap0.exr") && stderr.contains("would replace a file of an input"),
        "{stderr}"
    );
    assert_eq!(snapshot(&case.path("out")), before, "the output folder changed");
}

#[test]
fn a_folder_where_an_output_goes_leaves_the_output_folder_as_it_was() {
    let case = Case::new();
    std::fs::create_dir_all(case.path("out/good.lightmap0.exr")).unwrap();
    std::fs::write(case.path("out/report.json"), "{\"previous\": true}").unwrap();
    std::fs::copy(fixture("sphere.glb"), case.path("good.glb")).unwrap();
    let before = snapshot(&case.path("out"));
    let output = case.bake("good.glb");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("out/good.lightmap0.exr") && stderr.contains("is a folder"), "{stderr}");
    assert_eq!(snapshot(&case.path("out")), before, "the output folder changed");
}

#[test]
fn an_input_whose_outputs_names_would_be_too_long_is_refused_before_the_bake() {
    // The outputs add up to 24 bytes to the input's stem; 255 bytes is the
    // longest name the test's filesystem takes. Found at the export, after
    // the whole bake, it cost the run.
    let case = Case::new();
    let (fits, too_long) = ("f".repeat(255 - 24), "t".repeat(255 - 23));
    for stem in [&fits, &too_long] {
        std::fs::copy(fixture("sphere.glb"), case.path(&format!("{stem}.glb"))).unwrap();
    }
    let problem = "its name is 232 bytes before the extension; its outputs add up to 24 more, past the 255 bytes";
    case.refused(&[&format!("{too_long}.glb")], &too_long, problem);
    let output = case.bake(&format!("{fits}.glb"));
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(case.path(&format!("out/{fits}.lightmap0.ktx2")).exists());
}

// ---------------------------------------------------------------------------------------------
// Environments

fn write_exr(case: &Case, name: &str, map: &EnvironmentMap) {
    bake::environment::write_exr(map, case.path(name), ExrPrecision::Float, false).unwrap();
}

fn report(case: &Case) -> Report {
    serde_json::from_slice(&std::fs::read(case.path("out/report.json")).unwrap()).unwrap()
}

/// Runs a bake expected to succeed; returns the sphere's mean L_lm (red).
fn sphere_mean(case: &Case, args: &[&str]) -> (f64, Report) {
    std::fs::copy(fixture("sphere.glb"), case.path("sphere.glb")).unwrap();
    let mut all = vec!["sphere.glb"];
    all.extend_from_slice(args);
    let output = case.run(&all);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report = report(case);
    let stats = &report.scenes[0].energy[0].stats;
    assert_eq!(stats.invalid_texels, 0);
    (stats.mean_lightmap[0], report)
}

#[test]
fn non_finite_environment_texels_are_refused_or_clamped_when_asked() {
    let case = Case::new();
    std::fs::copy(fixture("sphere.glb"), case.path("sphere.glb")).unwrap();
    let mut map = EnvironmentMap::from_fn(64, 32, |_| [1.0; 3]);
    map.texels[100] = [f32::NAN, 1.0, 1.0];
    map.texels[900] = [f32::INFINITY; 3];
    map.texels[1500][2] = f32::NEG_INFINITY;
    write_exr(&case, "bad.exr", &map);
    case.refused(
        &["sphere.glb", "--env", "bad.exr"],
        "environment 'bad.exr'",
        "5 non-finite texel values (1 NaN, 3 +inf, 1 -inf) at (col,row) (36,1), (4,14), (28,23)",
    );
    // --clamp-nonfinite: NaN and -inf become 0, +inf the largest finite value (1 here), so the
    // sphere sees a white furnace of 1 short of 1.3 texels' worth of sky.
    let (mean, report) = sphere_mean(&case, &["--env", "bad.exr", "--clamp-nonfinite"]);
    let notices = &report.environment.as_ref().unwrap().notices;
    assert!(notices.iter().any(|n| n.contains("replaced 5 non-finite texel values")), "{notices:?}");
    eprintln!("clamped map: sphere mean L_lm {mean:.4}");
    assert!((mean - 1.0).abs() < 0.02, "mean L_lm {mean}");
}

#[test]
fn a_black_environment_is_an_error_without_emitters_and_ignored_with_them() {
    let case = Case::new();
    write_exr(&case, "black.exr", &EnvironmentMap::from_fn(64, 32, |_| [0.0; 3]));
    std::fs::copy(fixture("sphere.glb"), case.path("sphere.glb")).unwrap();
    case.refused(
        &["sphere.glb", "--env", "black.exr"],
        "environment 'black.exr'",
        "the map has no energy (every texel is black) and input 'sphere.glb' has no emissive materials",
    );
    // A lamp-lit room bakes under it, lit by the lamp alone.
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let mut scene = SceneBuilder::new();
    scene.object("room", &MeshData::room([4.0, 3.0, 4.0]), [0.7, 0.7, 0.7, 1.0], [0.0; 3], Placement::default());
    scene.object(
        "lamp",
        &MeshData::plane(1.0, 1.0, 1),
        [0.0, 0.0, 0.0, 1.0],
        [20.0; 3],
        Placement::at(glam::Vec3::new(0.0, 1.45, 0.0)).rotated(glam::Quat::from_rotation_x(std::f32::consts::PI)),
    );
    case.write("lamp.glb", &scene.to_glb());
    let output = case.run(&["lamp.glb", "--env", "black.exr"]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report = report(&case);
    let environment = report.environment.as_ref().unwrap();
    assert_eq!(environment.lights, 0);
    assert!(environment.notices.iter().any(|n| n.contains("no energy")), "{:?}", environment.notices);
    let scene = &report.scenes[0];
    assert!(scene.skipped.iter().any(|s| s.pass == "direct" && s.reason.contains("no energy")), "{:?}", scene.skipped);
    assert!(scene.energy[0].stats.mean_lightmap[0] > 0.1, "the lamp lit the room");
}

#[test]
fn a_one_by_one_map_is_a_constant_sky() {
    let case = Case::new();
    write_exr(&case, "one.exr", &EnvironmentMap { width: 1, height: 1, texels: vec![[0.5, 0.5, 0.5]] });
    let (mean, _) = sphere_mean(&case, &["--env", "one.exr"]);
    eprintln!("1×1 map of 0.5: sphere mean L_lm {mean:.4}");
    assert!((mean / 0.5 - 1.0).abs() < 0.02, "white furnace: mean L_lm {mean}, expected 0.5");
}

#[test]
fn maps_that_are_not_two_to_one_are_refused_with_their_size() {
    let case = Case::new();
    std::fs::copy(fixture("sphere.glb"), case.path("sphere.glb")).unwrap();
    for (w, h) in [(64, 64), (3, 1), (65, 32)] {
        let name = format!("map{w}x{h}.exr");
        write_exr(&case, &name, &EnvironmentMap::from_fn(w, h, |_| [1.0; 3]));
        case.refused(
            &["sphere.glb", "--env", &name],
            &format!("environment '{name}'"),
            &format!("not an equirectangular map: {w}×{h} is not 2:1"),
        );
    }
}

#[test]
fn a_large_map_bakes_in_bounded_memory() {
    // 8192×4096 (33.5 M texels, 403 MB as f32 RGB): a sky of 1 above the
    // horizon and 0.25 below, so the sphere's mean L_lm is (1 + 0.25)/2.
    let case = Case::new();
    let map = EnvironmentMap::from_fn(8192, 4096, |d| if d[1] > 0.0 { [1.0; 3] } else { [0.25; 3] });
    let map_bytes = (map.texels.len() * 12) as f64;
    bake::environment::write_hdr(&map, case.path("large.hdr")).unwrap();
    drop(map);
    let (mean, report) = sphere_mean(&case, &["--env", "large.hdr", "--lights", "64"]);
    let environment = report.environment.as_ref().unwrap();
    assert_eq!((environment.width, environment.height), (8192, 4096));
    let memory = environment.memory.as_ref().expect("the environment stage's memory is measured");
    let peak = memory.peak_rss_bytes as f64;
    eprintln!(
        "8192×4096 map: {:.1} s, peak RSS {:.0} MB ({:.2}× the map's f32 texels, scope {}); sphere mean L_lm {mean:.4}",
        environment.seconds,
        peak / 1e6,
        peak / map_bytes,
        memory.peak_rss_scope
    );
    // Measured 1.40× (565 MB): the decoded map plus one f32 copy at most.
    assert!(peak < 2.0 * map_bytes, "peak RSS {peak} for a map of {map_bytes} bytes");
    assert!((mean / 0.625 - 1.0).abs() < 0.02, "mean L_lm {mean}, expected 0.625");
}

#[test]
fn an_atlas_larger_than_the_adapter_allows_is_refused_naming_the_limit() {
    let case = Case::new();
    std::fs::copy(fixture("sphere.glb"), case.path("sphere.glb")).unwrap();
    let env = fixture("sky_constant.hdr");
    let line = case.refused(
        &["sphere.glb", "--env", env.to_str().unwrap(), "--max-atlas-size", "100000"],
        "--max-atlas-size 100000",
        "its largest texture is",
    );
    // The limit is the adapter's own, named with a number.
    let gpu = common::gpu();
    let max = gpu.limits.max_texture_dimension_2d;
    assert!(line.contains(&format!("{max}×{max} texels")) && line.contains(&gpu.adapter.name), "{line}");
    // One texel over the limit is refused too; the limit itself passes the check.
    let over = (max + 1).to_string();
    case.refused(&["sphere.glb", "--env", env.to_str().unwrap(), "--max-atlas-size", &over], &over, "largest texture");
    let mut options = bake::config::BakeOptions::default();
    options.unwrap.max_atlas_size = max;
    bake::check_adapter_limits(&gpu, &options).unwrap();
}

#[test]
fn morph_weights_that_do_not_match_the_targets_are_refused_naming_the_node() {
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let mut scene = SceneBuilder::new();
    let data = MeshData::cuboid([1.0; 3]);
    let cube = scene.mesh("box", &data, None);
    for shift in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        scene.morph_target(cube, "POSITION", &vec![shift; data.positions.len()]);
    }
    let node = scene.node("box", cube, Placement::default());
    scene.node_weights(node, &[0.5]);
    let case = Case::new();
    case.write("morph.glb", &scene.to_glb());
    case.refused(&["morph.glb"], "morph.glb", "node 0 lists 1 morph weights for the 2 morph targets of mesh 0");
}

#[test]
fn punctual_lights_that_cannot_be_are_refused_naming_the_light() {
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    for (light, problem) in [
        (
            json!({ "type": "spot", "name": "torch", "spot": { "innerConeAngle": 0.6, "outerConeAngle": 0.4 } }),
            "light 0 'torch' on node 1 'lamp': spot cone angles inner 0.6",
        ),
        (json!({ "type": "point", "intensity": -3.0 }), "light 0 on node 1 'lamp': colour × intensity"),
        (json!({ "type": "point", "range": 0.0 }), "light 0 on node 1 'lamp': range 0 is not a positive distance"),
        // As the file wrote it, not widened from its f32 (-0.10000000149011612).
        (json!({ "type": "point", "range": -0.1 }), "light 0 on node 1 'lamp': range -0.1 is not a positive distance"),
    ] {
        let mut scene = SceneBuilder::new();
        scene.object("ground", &MeshData::plane(2.0, 2.0, 1), [0.5; 4], [0.0; 3], Placement::default());
        scene.light("lamp", light, Placement::at(glam::Vec3::Y));
        let case = Case::new();
        case.write("lamp.glb", &scene.to_glb());
        case.refused(&["lamp.glb"], "lamp.glb", problem);
    }
}

// ---------------------------------------------------------------------------------------------
// Hostile inputs (issue 50)

/// Sets bytes `at..` of the first `name` attribute's value (after its name,
/// type and size) in an EXR header.
fn patch_exr_attribute(bytes: &mut [u8], name: &str, kind: &str, value: &[u8]) {
    let key = [name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat();
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    bytes[at..at + value.len()].copy_from_slice(value);
}

/// An EXR whose header declares a `width`×`height` image over the pixels of a 2×1 one, in
/// each of `windows` (its data or display window).
fn exr_declaring(case: &Case, width: i32, height: i32, windows: &[&str]) -> Vec<u8> {
    write_exr(case, "small.exr", &EnvironmentMap::from_fn(2, 1, |_| [1.0; 3]));
    let mut bytes = std::fs::read(case.path("small.exr")).unwrap();
    std::fs::remove_file(case.path("small.exr")).unwrap();
    let window: Vec<u8> = [0, 0, width - 1, height - 1].iter().flat_map(|v: &i32| v.to_le_bytes()).collect();
    for name in windows {
        patch_exr_attribute(&mut bytes, name, "box2i", &window);
    }
    bytes
}

#[test]
fn image_headers_declaring_more_than_the_file_holds_are_refused_before_allocating() {
    let case = Case::new();
    std::fs::copy(fixture("sphere_on_ground.glb"), case.path("scene.glb")).unwrap();
    for (width, height) in [(200000, 100000), (65536, 32768)] {
        let header = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n");
        case.write("huge.hdr", &[header.as_bytes(), &[2, 2, 0, 8, 1, 1, 1, 1]].concat());
        case.refused(&["scene.glb", "--env", "huge.hdr"], "huge.hdr", "declares");
        let exr = exr_declaring(&case, width, height, &["dataWindow", "displayWindow"]);
        case.write("huge.exr", &exr);
        case.refused(&["scene.glb", "--env", "huge.exr"], "huge.exr", "declares");
        // The 2×1 texels would be placed in the display window, black around them.
        case.write("display.exr", &exr_declaring(&case, width, height, &["displayWindow"]));
        case.refused(&["scene.glb", "--env", "display.exr"], "display.exr", "display window: the header declares");
    }
    // `bake check` re-reads a lightmap EXR beside the report.
    let out = tempfile::tempdir().unwrap();
    crate::common::bake_file(
        &fixture("sphere_on_ground.glb"),
        out.path(),
        &["--max-atlas-size", "32", "--lights", "16"],
    );
    let exr = exr_declaring(&case, 65536, 32768, &["dataWindow", "displayWindow"]);
    std::fs::write(out.path().join("sphere_on_ground.lightmap0.exr"), exr).unwrap();
    let output = finish({
        let mut command = common::bake_command();
        command.arg("check").arg(out.path().join("report.json"));
        command
    });
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("sphere_on_ground.lightmap0.exr") && stderr.contains("declares"), "{stderr}");
}

/// The fixture as a .gltf with `edit` applied to its JSON and its BIN chunk.
fn edited(case: &Case, name: &str, edit: impl FnOnce(&mut Value, &mut Vec<u8>)) {
    let (mut json, mut bin) = parts();
    edit(&mut json, &mut bin);
    case.write(name, &glb(&json, &bin));
}

#[test]
fn a_scene_smaller_than_a_micrometre_is_refused_naming_its_size_and_the_bound() {
    // Its form factors' r⁴ terms would leave f32's normal range: baked, a
    // scene 10⁻¹³ m across came out black with exit code 0.
    let case = Case::new();
    edited(&case, "tiny.glb", |json, _| {
        let roots = json["scenes"][0]["nodes"].clone();
        let nodes = json["nodes"].as_array_mut().unwrap();
        nodes.push(json!({ "name": "wrong unit", "scale": [1e-9, 1e-9, 1e-9], "children": roots }));
        json["scenes"][0]["nodes"] = json!([nodes.len() - 1]);
    });
    let line = case.refused(&["tiny.glb"], "tiny.glb", "the scene's longest side spans ");
    assert!(line.contains("less than the 1e-6 m bake accepts (glTF lengths are metres"), "{line}");
    assert!(line.contains("from vertex ") && line.contains(" of mesh 0 'ground' on node 0 'ground'"), "{line}");
}

#[test]
fn scenes_where_no_triangle_has_any_area_are_refused() {
    let case = Case::new();
    edited(&case, "scaled.glb", |json, _| {
        for node in json["nodes"].as_array_mut().unwrap() {
            node["scale"] = json!([0.0, 0.0, 0.0]);
        }
    });
    edited(&case, "points.glb", |json, bin| {
        for a in 0..json["accessors"].as_array().unwrap().len() {
            if json["accessors"][a]["type"] == "VEC3" && json["accessors"][a]["componentType"] == 5126 {
                json["accessors"][a]["min"] = json!([0.0, 0.0, 0.0]);
                json["accessors"][a]["max"] = json!([0.0, 0.0, 0.0]);
                let count = json["accessors"][a]["count"].as_u64().unwrap() as usize;
                let start = element_offset(json, a, 0);
                bin[start..start + count * 12].fill(0);
            }
        }
    });
    edited(&case, "same_index.glb", |json, bin| {
        for mesh in json["meshes"].as_array().unwrap().clone() {
            let a = mesh["primitives"][0]["indices"].as_u64().unwrap() as usize;
            let count = json["accessors"][a]["count"].as_u64().unwrap() as usize;
            let size = if json["accessors"][a]["componentType"] == 5125 { 4 } else { 2 };
            let start = element_offset(json, a, 0);
            bin[start..start + count * size].fill(0);
        }
    });
    for name in ["scaled.glb", "points.glb", "same_index.glb"] {
        case.refused(&[name], name, "no triangle has any area");
    }
}

#[test]
fn node_hierarchies_that_are_not_trees_are_refused_naming_the_nodes() {
    // Each would bake one node at two placements into its one set of UVs.
    type Edit = fn(&mut Value);
    let case = Case::new();
    let cases: [(&str, Edit, &str); 4] = [
        (
            "two_parents.glb",
            |json| {
                json["nodes"].as_array_mut().unwrap().push(json!({ "name": "left", "children": [1] }));
                json["nodes"].as_array_mut().unwrap().push(json!({ "name": "right", "children": [1] }));
                json["scenes"][0]["nodes"] = json!([0, 2, 3]);
            },
            "node 1 'sphere' is a child of both node 2 'left' and node 3 'right': a glTF node has one parent at most",
        ),
        ("own_child.glb", |json| json["nodes"][0]["children"] = json!([0]), "node 0 'ground' is its own child"),
        (
            "root_twice.glb",
            |json| json["scenes"][0]["nodes"] = json!([0, 1, 0]),
            "scene 0 lists node 0 'ground' twice among its root nodes",
        ),
        (
            "loop.glb",
            |json| {
                json["nodes"][0]["children"] = json!([1]);
                json["nodes"][1]["children"] = json!([0]);
            },
            "scene 0 lists node 0 'ground' as a root node, but it is a child of node 1 'sphere'",
        ),
    ];
    for (name, edit, problem) in cases {
        edited(&case, name, |json, _| edit(json));
        case.refused(&[name], name, problem);
    }
}

#[test]
fn a_scene_of_slivers_the_unwrap_cannot_chart_is_refused_as_such() {
    // Triangles of area (20 m long, 1 µm wide) that xatlas drops as
    // degenerate: the density is not the user's to raise.
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let mut slivers = MeshData::default();
    for k in 0..200u32 {
        let x = k as f32 * 0.01;
        slivers.positions.extend_from_slice(&[[x, 0.0, -10.0], [x + 1e-6, 0.0, 10.0], [x, 1e-6, 0.0]]);
        slivers.normals.extend_from_slice(&[[0.0, 1.0, 0.0]; 3]);
        slivers.uv0.extend_from_slice(&[[0.0, 0.0]; 3]);
        slivers.indices.extend_from_slice(&[3 * k, 3 * k + 1, 3 * k + 2]);
    }
    let mut scene = SceneBuilder::new();
    scene.object("slivers", &slivers, [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let case = Case::new();
    case.write("slivers.glb", &scene.to_glb());
    let line = case.refused(&["slivers.glb"], "slivers.glb", "the unwrap laid out none of the scene's triangles");
    assert!(!line.contains("--texels-per-unit"), "{line}");
}

#[test]
fn a_density_that_yields_no_texels_is_a_user_error() {
    let case = Case::new();
    std::fs::copy(fixture("sphere_on_ground.glb"), case.path("scene.glb")).unwrap();
    let env = fixture("sky_constant.hdr");
    for density in ["1e-30", "1e-9"] {
        let line = case.refused(
            &["scene.glb", "--env", env.to_str().unwrap(), "--texels-per-unit", density],
            "scene.glb",
            "no lightmap texel",
        );
        assert!(line.contains("--texels-per-unit"), "{line}");
    }
}

/// `bake check` of `out`'s report: its exit code and stdout + stderr.
fn check(out: &Path) -> (Option<i32>, String) {
    let output = finish({
        let mut command = common::bake_command();
        command.arg("check").arg(out.join("report.json"));
        command
    });
    (
        output.status.code(),
        format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr)),
    )
}

#[test]
fn check_fails_when_the_lightmap_beside_the_report_is_missing_or_no_file() {
    let out = tempfile::tempdir().unwrap();
    crate::common::bake_file(
        &fixture("sphere_on_ground.glb"),
        out.path(),
        &["--max-atlas-size", "32", "--lights", "16"],
    );
    let lightmap = out.path().join("sphere_on_ground.lightmap0.exr");
    assert_eq!(check(out.path()).0, Some(0));
    std::fs::rename(&lightmap, out.path().join("sphere_on_ground.lightmap0.exr.kept")).unwrap();
    let (code, text) = check(out.path());
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("sphere_on_ground.lightmap0.exr") && text.contains("missing"), "{text}");
    // Beside the report but no file: a folder, a FIFO (which must not block the check).
    std::fs::create_dir(&lightmap).unwrap();
    let fifo = out.path().join("sphere_on_ground.lightmap0.ktx2");
    std::fs::remove_file(&fifo).unwrap();
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let (code, text) = check(out.path());
    assert_ne!(code, Some(0), "{text}");
    assert!(text.contains("sphere_on_ground.lightmap0.exr") && text.contains("not a regular file"), "{text}");
    std::fs::remove_dir(&lightmap).unwrap();
    std::fs::copy(out.path().join("sphere_on_ground.lightmap0.exr.kept"), &lightmap).unwrap();
    let (code, text) = check(out.path());
    assert_ne!(code, Some(0), "{text}");
    assert!(text.contains("sphere_on_ground.lightmap0.ktx2") && text.contains("not a regular file"), "{text}");
    // A link to a device or a folder outside is not even opened.
    for target in ["/dev/zero", "/"] {
        let _ = std::fs::remove_file(&lightmap);
        std::os::unix::fs::symlink(target, &lightmap).unwrap();
        let (code, text) = check(out.path());
        assert_eq!(code, Some(2), "{text}");
        assert!(text.contains("sphere_on_ground.lightmap0.exr") && text.contains("resolves outside"), "{text}");
    }
}

#[test]
fn command_line_errors_are_one_line_naming_the_option_value_and_range() {
    let case = Case::new();
    std::fs::copy(fixture("sphere_on_ground.glb"), case.path("scene.glb")).unwrap();
    for (option, value, range) in [
        ("--padding", "-1", "0..=64"),
        ("--padding", "65", "0..=64"),
        ("--lights", "-1", "-1"),
        ("--tolerance", "-1", "[0, 1)"),
        ("--max-atlas-size", "-5", "16.."),
        ("--patches", "0", "1..=1048576"),
        ("--max-shots", "x", "x"),
        ("--max-shots", "-1", "0.."),
        ("--reference", "-1", "1..=65536"),
        ("--max-triangles", "0", "1.."),
        ("--gpu-timeout", "1e300", "[0, 1e9]"),
        ("--texels-per-unit", "-2", "positive"),
    ] {
        let line = case.refused(&["scene.glb", option, value], option, value);
        assert!(line.contains(range), "{line}");
    }
    case.refused(&["scene.glb", "--no-such-option"], "--no-such-option", "unexpected");
}

#[test]
fn a_file_name_with_control_characters_is_printed_escaped_in_the_log() {
    // The scene is named after its file: its stage lines and the summary
    // must neither split nor send the terminal an escape sequence.
    let case = Case::new();
    let name = "a\nb\x1b[31m.glb";
    std::fs::copy(fixture("sphere_on_ground.glb"), case.path(name)).unwrap();
    let env = fixture("sky_constant.hdr");
    let output = common::bake_command()
        .current_dir(case.dir.path())
        .args([name, "--env", env.to_str().unwrap(), "-o", "out", "--max-atlas-size", "32", "--lights", "16"])
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{log}");
    assert!(!log.contains('\x1b'), "an escape sequence reached the terminal: {log:?}");
    assert!(log.lines().any(|l| l.contains("a\\nb\\u{1b}[31m import: ")), "{log}");
    assert!(log.lines().any(|l| l.contains("out/a\\nb\\u{1b}[31m.glb")), "{log}");
}

#[test]
fn control_characters_from_the_input_are_escaped() {
    let case = Case::new();
    let (json, bin) = parts();
    let mut bytes = glb(&json, &bin);
    bytes[16..20].copy_from_slice(b"\x1b[2J");
    case.write("escape.glb", &bytes);
    case.refused(&["escape.glb"], "escape.glb", "\\u{1b}[2J");
    for (name, uri) in [("newline.gltf", "a%0Ab.bin"), ("nul.gltf", "a%00b.bin"), ("bell.gltf", "a%07b.bin")] {
        gltf_with_buffer(&case, name, uri);
        let line = case.refused(&[name], name, "buffer 0");
        assert!(!line.chars().any(char::is_control), "{line:?}");
    }
}

#[test]
fn staging_folders_are_removed_on_a_signal_and_stale_ones_on_the_next_run() {
    let case = Case::new();
    std::fs::copy(fixture("sphere_on_ground.glb"), case.path("scene.glb")).unwrap();
    let staging = |case: &Case| -> Vec<String> {
        let entries = std::fs::read_dir(case.path("out")).map(|d| d.map(|e| e.unwrap().file_name()).collect());
        let entries: Vec<_> = entries.unwrap_or_default();
        entries.iter().map(|n| n.to_string_lossy().into_owned()).filter(|n| n.starts_with(".bake-staging-")).collect()
    };
    let env = fixture("sky_sun.exr");
    // An existing output folder holds the staging folder.
    std::fs::create_dir(case.path("out")).unwrap();
    for signal in ["INT", "TERM"] {
        let mut child = common::bake_command()
            .current_dir(case.path(""))
            .args(["scene.glb", "--env", env.to_str().unwrap(), "-o", "out", "-q", "--max-atlas-size", "256"])
            .spawn()
            .unwrap();
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
        while staging(&case).is_empty() {
            assert!(std::time::Instant::now() < deadline && child.try_wait().unwrap().is_none(), "no staging folder");
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let pid = child.id().to_string();
        assert!(Command::new("kill").args(["-s", signal, &pid]).status().unwrap().success());
        let status = child.wait().unwrap();
        assert!(!status.success());
        assert_eq!(staging(&case), Vec::<String>::new(), "SIG{signal} left the staging folder");
    }
    // One a killed run left: its process is gone, so the next run removes it.
    std::fs::create_dir_all(case.path("out/.bake-staging-999999999/x")).unwrap();
    std::fs::create_dir_all(case.path("out/.bake-staging-notapid")).unwrap();
    let output = case.run(&["scene.glb", "--env", env.to_str().unwrap()]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert_eq!(staging(&case), [".bake-staging-notapid"]);
    // A run's lock, not its process id, says it is alive: a run in another
    // PID namespace or on another host sharing the folder (here this test,
    // holding the lock of a folder named after no process of this one) keeps
    // its folder; once the lock is released, the next run removes it.
    let live = case.path("out/.bake-staging-999999998");
    std::fs::create_dir_all(&live).unwrap();
    let lock = std::fs::File::create(live.join(".lock")).unwrap();
    lock.lock().unwrap();
    let output = case.run(&["scene.glb", "--env", env.to_str().unwrap()]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert_eq!(staging(&case), [".bake-staging-999999998", ".bake-staging-notapid"]);
    drop(lock);
    let output = case.run(&["scene.glb", "--env", env.to_str().unwrap()]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert_eq!(staging(&case), [".bake-staging-notapid"]);
}

#[test]
fn finite_scene_values_that_would_overflow_are_refused_naming_value_place_and_bound() {
    let case = Case::new();
    // A node scaled by 10³⁰: triangle areas of 10⁶⁰ m², far past f32.
    edited(&case, "scaled.glb", |json, _| json["nodes"][0]["scale"] = json!([1e30, 1e30, 1e30]));
    let line = case.refused(&["scaled.glb"], "scaled.glb", "the scene spans 1e31 m along x, more than the 1e7 m");
    assert!(line.contains("vertex 0 of mesh 0 'ground' on node 0 'ground', primitive 0 at x = -5e30"), "{line}");
    // One vertex 10³⁸ m out.
    edited(&case, "stray.glb", |json, bin| {
        let at = element_offset(
            json,
            json["meshes"][1]["primitives"][0]["attributes"]["POSITION"].as_u64().unwrap() as usize,
            5,
        );
        bin[at..at + 4].copy_from_slice(&(-1e38f32).to_le_bytes());
    });
    case.refused(
        &["stray.glb"],
        "stray.glb",
        "from vertex 5 of mesh 1 'sphere' on node 1 'sphere', primitive 0 at x = -1e38",
    );
    // KHR_materials_emissive_strength of 10³⁸, and a negative one.
    for (name, strength, shown) in [("glow.glb", 1e38, "1e38"), ("dark.glb", -5.0, "-5")] {
        edited(&case, name, |json, _| {
            json["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
            json["materials"][1]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
            json["materials"][1]["extensions"] =
                json!({ "KHR_materials_emissive_strength": { "emissiveStrength": strength } });
        });
        case.refused(
            &[name],
            name,
            &format!(
                "material 1 'sphere': emission (emissiveFactor × KHR_materials_emissive_strength) {shown} is not a \
                      radiance bake accepts: finite, ≥ 0 and at most 1e12"
            ),
        );
    }
    // A point light of 10³⁸ candela.
    edited(&case, "lamp.glb", |json, _| {
        json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
        json["extensions"] = json!({ "KHR_lights_punctual": { "lights": [{ "type": "point", "intensity": 1e38 }] } });
        json["nodes"].as_array_mut().unwrap().push(json!({ "translation": [0.0, 3.0, 0.0],
            "extensions": { "KHR_lights_punctual": { "light": 0 } } }));
        json["scenes"][0]["nodes"].as_array_mut().unwrap().push(json!(2));
    });
    case.refused(&["lamp.glb"], "lamp.glb", "light 0 on node 2: colour × intensity 1e38 is more than the 1e12");
}

#[test]
fn environments_that_would_overflow_are_refused_naming_the_texel_and_bound() {
    let case = Case::new();
    std::fs::copy(fixture("sphere.glb"), case.path("sphere.glb")).unwrap();
    let mut map = EnvironmentMap::from_fn(64, 32, |_| [1.0; 3]);
    map.texels[3 * 64 + 5] = [3e38, 1.0, 1.0];
    write_exr(&case, "hot.exr", &map);
    case.refused(
        &["sphere.glb", "--env", "hot.exr"],
        "environment 'hot.exr'",
        "texel (col,row) (5,3) is 3e38, more radiance than the 1e12 bake accepts",
    );
    write_exr(&case, "sky.exr", &EnvironmentMap::from_fn(64, 32, |_| [1.0; 3]));
    case.refused(
        &["sphere.glb", "--env", "sky.exr", "--env-intensity", "1e38"],
        "environment 'sky.exr'",
        "is 1 × --env-intensity 1e38 = 1e38, more radiance than the 1e12",
    );
    // At the bound it bakes, every texel finite.
    let (mean, _) = sphere_mean(&case, &["--env", "sky.exr", "--env-intensity", "1e12"]);
    assert!((mean / 1e12 - 1.0).abs() < 0.02, "mean L_lm {mean}");
}

#[test]
fn a_scene_over_the_triangle_budget_is_refused_before_it_is_read() {
    let case = Case::new();
    // 587 KB of glTF drawing the sphere from 10 000 nodes: 22 M triangles.
    edited(&case, "crowd.glb", |json, _| {
        let nodes = json["nodes"].as_array_mut().unwrap();
        let first = nodes.len();
        nodes.extend(
            (0..10_000)
                .map(|i| json!({ "mesh": 1, "translation": [(i % 100) as f64 * 2.0, 0.0, (i / 100) as f64 * 2.0] })),
        );
        json["scenes"][0]["nodes"] = json!((0..first + 10_000).collect::<Vec<_>>());
    });
    let start = std::time::Instant::now();
    let line = case.refused(&["crowd.glb"], "crowd.glb", "the scene draws 22082240 triangles");
    assert!(line.contains("more than the budget of 4000000 (--max-triangles): raise --max-triangles"), "{line}");
    assert!(start.elapsed().as_secs_f64() < 10.0, "refused only after {:?}", start.elapsed());
    // The budget is the user's to set: the fixture's 2240 triangles need 2240.
    std::fs::copy(fixture("sphere_on_ground.glb"), case.path("scene.glb")).unwrap();
    case.refused(
        &["scene.glb", "--max-triangles", "2239"],
        "scene.glb",
        "draws 2240 triangles (node and GPU instances expanded), more than the budget of 2239",
    );
    let env = fixture("sky_constant.hdr");
    let output = case.run(&["scene.glb", "--env", env.to_str().unwrap(), "--max-triangles", "2240"]);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
}

#[test]
fn a_triangle_drawn_by_more_gpu_instances_than_the_budget_is_refused_before_it_is_read() {
    // Each instance becomes a mesh of its own in the output: one triangle
    // drawn 100,000 times from a 1.2 MB file took 2.4 GB and wrote 134 MB.
    let case = Case::new();
    let instances = 100_000u64;
    edited(&case, "instances.glb", |json, bin| {
        let sphere = &json["meshes"][1]["primitives"][0];
        let mut corners = json["accessors"][sphere["attributes"]["POSITION"].as_u64().unwrap() as usize].clone();
        corners["count"] = json!(3);
        let offset = bin.len();
        bin.resize(offset + 12 * instances as usize, 0);
        json["bufferViews"].as_array_mut().unwrap().push(json!({
            "buffer": 0, "byteOffset": offset, "byteLength": 12 * instances
        }));
        json["buffers"][0]["byteLength"] = json!(bin.len());
        let view = json["bufferViews"].as_array().unwrap().len() - 1;
        let accessors = json["accessors"].as_array_mut().unwrap();
        accessors.push(corners);
        accessors.push(json!({ "bufferView": view, "componentType": 5126, "count": instances, "type": "VEC3" }));
        let (corners, translations) = (accessors.len() - 2, accessors.len() - 1);
        let meshes = json["meshes"].as_array_mut().unwrap();
        meshes.push(json!({ "primitives": [{ "attributes": { "POSITION": corners } }] }));
        let mesh = meshes.len() - 1;
        let nodes = json["nodes"].as_array_mut().unwrap();
        nodes.push(json!({ "mesh": mesh, "extensions": {
            "EXT_mesh_gpu_instancing": { "attributes": { "TRANSLATION": translations } }
        } }));
        let node = nodes.len() - 1;
        json["scenes"][0]["nodes"].as_array_mut().unwrap().push(json!(node));
        json["extensionsUsed"] = json!(["EXT_mesh_gpu_instancing"]);
    });
    let problem = format!(
        "draws {} primitives (node and GPU instances expanded, each a mesh of its own in the output), more than the \
         budget of 62500 (one per 64 triangles of --max-triangles)",
        instances + 2
    );
    case.refused(&["instances.glb"], "instances.glb", &problem);
}

#[test]
fn primitives_reading_more_vertices_than_the_budget_are_refused_before_they_are_read() {
    // 64 more primitives on the sphere, each drawing one triangle out of the
    // sphere's whole POSITION accessor, as a 22 M-vertex accessor (a sparse
    // one needs no data) drawn for a few triangles would.
    let case = Case::new();
    let mut expected = (0, 0);
    edited(&case, "shared.glb", |json, _| {
        let sphere = json["meshes"][1]["primitives"][0].clone();
        let mut one = json["accessors"][sphere["indices"].as_u64().unwrap() as usize].clone();
        one["count"] = json!(3);
        one.as_object_mut().unwrap().remove("min");
        one.as_object_mut().unwrap().remove("max");
        let accessors = json["accessors"].as_array_mut().unwrap();
        accessors.push(one);
        let extra = json!({ "attributes": sphere["attributes"], "indices": accessors.len() - 1 });
        json["meshes"][1]["primitives"].as_array_mut().unwrap().extend(std::iter::repeat_n(extra, 64));
        let count = |a: &Value| json["accessors"][a.as_u64().unwrap() as usize]["count"].as_u64().unwrap();
        for primitive in json["meshes"].as_array().unwrap().iter().flat_map(|m| m["primitives"].as_array().unwrap()) {
            expected.0 += count(&primitive["indices"]) / 3;
            expected.1 += count(&primitive["attributes"]["POSITION"]);
        }
    });
    let (triangles, vertices) = expected;
    assert_eq!(triangles, 2240 + 64);
    let budget = triangles.to_string();
    let problem = format!(
        "the scene's primitives read {vertices} vertices (node and GPU instances expanded), more than the budget of {} (3 a triangle of --max-triangles)",
        3 * triangles
    );
    case.refused(&["shared.glb", "--max-triangles", &budget], "shared.glb", &problem);
    // Within the budget it bakes.
    let env = fixture("sky_constant.hdr");
    let enough = vertices.div_ceil(3).to_string();
    let args = ["shared.glb", "--env", env.to_str().unwrap(), "--max-triangles", &enough, "--max-atlas-size", "128"];
    let output = case.run(&args);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
}

/// Runs `command` with at most `bytes` of data memory (RLIMIT_DATA: heap
/// and private writable mappings): its exit code, `None` when it died of a
/// signal (an allocation refused aborts the process).
fn exit_within_data_limit(mut command: Command, bytes: u64) -> Option<i32> {
    use std::os::unix::process::CommandExt;
    let limit = libc::rlimit { rlim_cur: bytes as libc::rlim_t, rlim_max: bytes as libc::rlim_t };
    // SAFETY: setrlimit is async-signal-safe, as code between fork and exec must be.
    unsafe {
        command.pre_exec(move || match libc::setrlimit(libc::RLIMIT_DATA, &limit) {
            0 => Ok(()),
            _ => Err(std::io::Error::last_os_error()),
        });
    }
    // Its table, one line per missing mesh, would fill a pipe nobody reads.
    let status = command.stdout(std::process::Stdio::null()).stderr(std::process::Stdio::null()).status();
    status.expect("bake runs").code()
}

#[test]
fn check_reads_a_large_golden_report_in_bounded_memory() {
    let out = tempfile::tempdir().unwrap();
    crate::common::bake_file(
        &fixture("sphere_on_ground.glb"),
        out.path(),
        &["--max-atlas-size", "32", "--lights", "16"],
    );
    let mut golden: Value = serde_json::from_slice(&std::fs::read(out.path().join("report.json")).unwrap()).unwrap();
    // About 50 MB: 20 000 meshes the bake does not have, and a long convergence trace.
    let scene = &mut golden["scenes"][0];
    let mesh = scene["energy"][0].clone();
    let meshes = (0..20_000).map(|i| {
        let mut mesh = mesh.clone();
        mesh["node"] = json!(1000 + i);
        mesh
    });
    scene["energy"].as_array_mut().unwrap().extend(meshes);
    let trace = scene["bounce"]["trace"].as_array_mut().expect("the fixture bounces light");
    let point = trace[0].clone();
    trace.extend(std::iter::repeat_n(point, 100_000));
    let bytes = serde_json::to_vec_pretty(&golden).unwrap();
    drop(golden);
    std::fs::write(out.path().join("golden.json"), &bytes).unwrap();
    let mut command = common::bake_command();
    command.current_dir(out.path()).args(["check", "report.json", "--against", "golden.json"]);
    // Read whole and parsed into a JSON tree, it took 4 times the file (1.2 GB for 285 MB);
    // streamed, it needs less than the file's size.
    let code = exit_within_data_limit(command, bytes.len() as u64);
    assert_eq!(code, Some(1), "a check of 20 000 missing meshes within {} bytes of memory", bytes.len());
}
