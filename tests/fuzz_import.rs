//! A property-based fuzzer of the glTF importer: valid GLBs (the fixtures)
//! with bytes flipped, cut short, or numbers and fields of their JSON chunk
//! changed (counts, offsets, strides, indices, component types, modes) must
//! give `SourceAsset::from_bytes` + `import::from_asset` an error or a scene,
//! never a panic, and never an allocation out of proportion to the input.
//! Every crash it found is kept below as a named regression test.
//!
//! The same holds for the other readers of untrusted files: the
//! environment (`.exr` and `.hdr`, through `load_environment`, the path
//! `--env` takes) and `bake check`'s report JSON and lightmap EXR (through
//! `read_report` and the checks run on it, and `lightmap_violations`),
//! mutated the same ways from small valid seeds.
//!
//! The case counts keep the whole file to a few seconds; raise them with
//! BAKE_FUZZ_ITERATIONS=N (cases per test; PROPTEST_CASES also works) for a
//! longer run.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use proptest::prelude::*;
use proptest::sample::Index;
use serde_json::{Value, json};

/// Records the largest single allocation request of the process.
struct Counting;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// One case at a time, so the largest allocation belongs to the case measured.
static SERIAL: Mutex<()> = Mutex::new(());

/// The importer may allocate no single block larger than this: the cap on an
/// accessor without a buffer view (256 MiB of zeros) plus room for one
/// converted copy of it. Real inputs stay far below (the fixtures: < 1 MiB).
const LARGEST_ALLOWED: usize = 512 << 20;

/// Imports `bytes` as an in-memory `.glb` (external files refused), reading
/// every accessor too, and returns the error text or "ok" and the largest
/// allocation it made. Panics propagate: they are what the fuzzer looks for.
fn import(bytes: &[u8]) -> (String, usize) {
    import_within(bytes, bake::limits::DEFAULT_MAX_TRIANGLES)
}

/// `import` within a triangle budget of `max_triangles` (and so three times as many vertices).
fn import_within(bytes: &[u8], max_triangles: u64) -> (String, usize) {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    LARGEST.store(0, Ordering::Relaxed);
    let outcome = (|| -> anyhow::Result<()> {
        let source = bake::asset::SourceAsset::from_bytes(Path::new("fuzz.glb"), bytes, None)?;
        for accessor in source.document.accessors() {
            let _ = bake::asset::accessor::read_floats(&source, &accessor);
            let _ = bake::asset::accessor::read_indices(&source, &accessor);
        }
        bake::import::from_asset_with(source, &bake::import::ImportOptions { max_triangles })?;
        Ok(())
    })();
    let largest = LARGEST.load(Ordering::Relaxed);
    (outcome.map_or_else(|e| format!("{e:#}"), |()| "ok".into()), largest)
}

fn check(bytes: &[u8]) -> Result<(), TestCaseError> {
    let (outcome, largest) = import(bytes);
    prop_assert!(largest <= LARGEST_ALLOWED.max(8 * bytes.len()), "allocated {largest} bytes ({outcome})");
    Ok(())
}

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures").join(name)).unwrap()
}

/// A fixture GLB as (JSON, BIN).
fn parts(name: &str) -> (Value, Vec<u8>) {
    let bytes = fixture(name);
    let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
    (serde_json::from_slice(&glb.json).unwrap(), glb.bin.map(|b| b.into_owned()).unwrap_or_default())
}

fn glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    bake::export::glb::encode(&serde_json::to_vec(json).unwrap(), bin)
}

/// JSON pointers to every number (`numbers`) and every object member (`members`) of `value`.
fn pointers(value: &Value, at: String, numbers: &mut Vec<String>, members: &mut Vec<String>) {
    match value {
        Value::Number(_) => numbers.push(at),
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                pointers(item, format!("{at}/{i}"), numbers, members);
            }
        }
        Value::Object(map) => {
            for (key, item) in map {
                let child = format!("{at}/{}", key.replace('~', "~0").replace('/', "~1"));
                members.push(child.clone());
                pointers(item, child, numbers, members);
            }
        }
        _ => {}
    }
}

/// What to do to the JSON chunk.
#[derive(Clone, Debug)]
enum Edit {
    /// Set a number to a value.
    Set(Index, Value),
    /// Add to a number (an off-by-some count, offset or index).
    Add(Index, i64),
    /// Remove an object member (a bufferView, indices, a required field).
    Remove(Index),
    /// Set an accessor's type.
    Type(Index, &'static str),
}

fn interesting_number() -> impl Strategy<Value = Value> {
    prop_oneof![
        prop::sample::select(vec![
            json!(0),
            json!(1),
            json!(-1),
            json!(2),
            json!(3),
            json!(4),
            json!(6),
            json!(7),
            json!(255),
            json!(256),
            json!(65535),
            json!(65536),
            json!(i32::MAX),
            json!(1u64 << 31),
            json!(u32::MAX),
            json!(1u64 << 32),
            json!(1u64 << 53),
            json!(u64::MAX),
            json!(i64::MIN),
            json!(1e300),
            json!(-1e300),
            json!(0.5),
        ]),
        // Component types, valid and not.
        (5118u32..5128).prop_map(|c| json!(c)),
        // Primitive modes, valid and not.
        (0u32..9).prop_map(|m| json!(m)),
        any::<u32>().prop_map(|v| json!(v)),
        any::<i64>().prop_map(|v| json!(v)),
    ]
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (any::<Index>(), interesting_number()).prop_map(|(i, v)| Edit::Set(i, v)),
        3 => (any::<Index>(), -16i64..=16).prop_map(|(i, d)| Edit::Add(i, d)),
        1 => any::<Index>().prop_map(Edit::Remove),
        1 => (any::<Index>(), prop::sample::select(vec!["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4", "VEC5"]))
            .prop_map(|(i, t)| Edit::Type(i, t)),
    ]
}

/// Applies `edits` to a fixture's JSON and packs it again with its own BIN.
fn edited(name: &str, edits: &[Edit]) -> Vec<u8> {
    let (mut json, bin) = parts(name);
    apply(&mut json, edits);
    glb(&json, &bin)
}

/// Applies `edits` to `json`: numbers set or shifted, members removed, accessor types changed.
fn apply(json: &mut Value, edits: &[Edit]) {
    for edit in edits {
        let (mut numbers, mut members) = (Vec::new(), Vec::new());
        pointers(json, String::new(), &mut numbers, &mut members);
        match edit {
            Edit::Set(i, value) => {
                if numbers.is_empty() {
                    continue;
                }
                let pointer: &String = i.get(&numbers);
                *json.pointer_mut(pointer).unwrap() = value.clone();
            }
            Edit::Add(i, delta) => {
                if numbers.is_empty() {
                    continue;
                }
                let pointer: &String = i.get(&numbers);
                let target = json.pointer_mut(pointer).unwrap();
                *target = match (target.as_i64(), target.as_f64()) {
                    (Some(n), _) => json!(n.saturating_add(*delta)),
                    (None, Some(x)) => json!(x + *delta as f64),
                    _ => continue,
                };
            }
            Edit::Remove(i) => {
                if members.is_empty() {
                    continue;
                }
                let pointer: String = i.get(members.as_slice()).clone();
                let (parent, key) = pointer.rsplit_once('/').unwrap();
                let key = key.replace("~1", "/").replace("~0", "~");
                json.pointer_mut(parent).and_then(Value::as_object_mut).map(|o| o.remove(&key));
            }
            Edit::Type(i, kind) => {
                let count = json["accessors"].as_array().map_or(0, Vec::len);
                if count > 0 {
                    json["accessors"][i.index(count)]["type"] = json!(kind);
                }
            }
        }
    }
}

const SEEDS: [&str; 2] = ["sphere_on_ground.glb", "everything.glb"];

fn config(cases: u32) -> ProptestConfig {
    let set = |name: &str| std::env::var(name).ok().and_then(|c| c.parse().ok());
    let cases = set("BAKE_FUZZ_ITERATIONS").or_else(|| set("PROPTEST_CASES")).unwrap_or(cases);
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

proptest! {
    #![proptest_config(config(400))]

    #[test]
    fn edited_json_never_panics(seed in 0..SEEDS.len(), edits in prop::collection::vec(edit(), 1..5)) {
        check(&edited(SEEDS[seed], &edits))?;
    }
}

proptest! {
    #![proptest_config(config(200))]

    #[test]
    fn flipped_bytes_never_panic(seed in 0..SEEDS.len(), flips in prop::collection::vec((any::<Index>(), 1u8..), 1..16)) {
        let mut bytes = fixture(SEEDS[seed]);
        for (at, mask) in &flips {
            let at = at.index(bytes.len());
            bytes[at] ^= mask;
        }
        check(&bytes)?;
    }

    #[test]
    fn flipped_header_and_json_bytes_never_panic(seed in 0..SEEDS.len(), flips in prop::collection::vec((0usize..64, any::<u8>()), 1..6)) {
        // The first 64 bytes: GLB header, chunk header and the start of the JSON.
        let mut bytes = fixture(SEEDS[seed]);
        for &(at, value) in &flips {
            bytes[at] = value;
        }
        check(&bytes)?;
    }

    #[test]
    fn truncated_files_never_panic(seed in 0..SEEDS.len(), cut in any::<Index>()) {
        let bytes = fixture(SEEDS[seed]);
        check(&bytes[..cut.index(bytes.len())])?;
    }
}

// ---------------------------------------------------------------------------------------------
// Environment maps and `bake check`'s inputs: read from files, as the CLI reads them.

/// Runs `read` on `bytes` written to a file of its own (the readers take
/// paths, as the CLI's do) and returns its error text or "ok" and the
/// largest allocation it made. Panics propagate.
fn read_file(bytes: &[u8], name: &str, read: impl FnOnce(&Path) -> anyhow::Result<()>) -> (String, usize) {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = scratch();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    LARGEST.store(0, Ordering::Relaxed);
    let outcome = read(&path);
    let largest = LARGEST.load(Ordering::Relaxed);
    let outcome = outcome.map_or_else(|e| format!("{e:#}"), |()| "ok".into());
    // BAKE_FUZZ_SHOW=1: each case's outcome, to see how deep the mutations reach.
    if std::env::var_os("BAKE_FUZZ_SHOW").is_some() {
        eprintln!("{name}: {outcome}");
    }
    (outcome, largest)
}

fn scratch() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Image readers may decode at most their format's densest coding of the
/// file's bytes (1032 decoded bytes per byte of deflate, README "Bad
/// input"), plus room for the copies a reader makes.
fn image_allocation_allowed(bytes: &[u8]) -> usize {
    (bytes.len() * 1032 * 2).max(16 << 20)
}

/// `--env FILE` as the CLI loads it: read, sanitised, bounded, turned into lights.
fn load_environment(path: &Path) -> anyhow::Result<()> {
    bake::load_environment(path, &bake::config::EnvironmentOptions::default()).map(|_| ())
}

fn check_environment(bytes: &[u8], name: &str) -> Result<(), TestCaseError> {
    let (outcome, largest) = read_file(bytes, name, load_environment);
    prop_assert!(largest <= image_allocation_allowed(bytes), "allocated {largest} bytes ({outcome})");
    Ok(())
}

/// Environment seeds: the small fixtures, and maps written here in the
/// codings the fixtures lack (half and tiled EXR, run-length HDR).
fn environment_seeds() -> Vec<(Vec<u8>, &'static str)> {
    use bake::environment::{EnvironmentMap, ExrPrecision, write_exr, write_hdr};
    let mut seeds: Vec<(Vec<u8>, &'static str)> = ["sky_constant.exr", "sky_horizon.exr"]
        .into_iter()
        .map(|name| (fixture(name), "env.exr"))
        .chain(["sky_constant.hdr", "sky_horizon.hdr"].into_iter().map(|name| (fixture(name), "env.hdr")))
        .collect();
    let map = EnvironmentMap::from_fn(32, 16, |d| [d[0].abs() * 4.0, d[1].max(0.0), 0.25]);
    let dir = scratch();
    for (precision, tiled) in [(ExrPrecision::Half, false), (ExrPrecision::Float, true)] {
        let path = dir.path().join("seed.exr");
        write_exr(&map, &path, precision, tiled).unwrap();
        seeds.push((std::fs::read(&path).unwrap(), "env.exr"));
    }
    let path = dir.path().join("seed.hdr");
    write_hdr(&map, &path).unwrap();
    seeds.push((std::fs::read(&path).unwrap(), "env.hdr"));
    seeds
}

/// A committed golden report: the seed of the report mutations.
fn golden_report() -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("pipeline/golden/sphere_on_ground.json")).unwrap()
}

/// `bake check REPORT --against GOLDEN` on a report: read it, check each
/// scene's invariants and energy balance, compare it with the golden one.
fn check_report(bytes: &[u8]) -> Result<(), TestCaseError> {
    let golden =
        bake::check::read_report(&Path::new(env!("CARGO_MANIFEST_DIR")).join("pipeline/golden/sphere_on_ground.json"))
            .unwrap();
    let (outcome, largest) = read_file(bytes, "report.json", |path| {
        let report = bake::check::read_report(path)?;
        for scene in &report.scenes {
            let _ = bake::check::invariants(scene);
            let _ = bake::check::energy_balance(scene);
        }
        let _ = bake::check::compare(&report, &golden, 0.02, None);
        Ok(())
    });
    prop_assert!(largest <= (64 * bytes.len()).max(16 << 20), "allocated {largest} bytes ({outcome})");
    Ok(())
}

/// The scene `bake check` checks a lightmap against (the golden report's),
/// and a lightmap EXR of its atlas size as export writes it.
fn lightmap_seed() -> (bake::report::SceneReport, Vec<u8>) {
    let report =
        bake::check::read_report(&Path::new(env!("CARGO_MANIFEST_DIR")).join("pipeline/golden/sphere.json")).unwrap();
    let scene = report.scenes[0].clone();
    let (width, height) = (scene.atlas.width, scene.atlas.height);
    let n = (width * height) as usize;
    let pixels = (0..n).map(|i| [(i % 7) as f32 * 0.5, (i % 13) as f32, 1.0]).collect();
    let image = bake::export::lightmap::Image { width, height, pixels, written: vec![true; n], chart: vec![0; n] };
    (scene, image.encode_exr().unwrap())
}

fn check_lightmap(scene: &bake::report::SceneReport, bytes: &[u8]) -> Result<(), TestCaseError> {
    let (outcome, largest) = read_file(bytes, "scene.lightmap0.exr", |path| {
        let (file, length) = bake::files::open(path)?;
        bake::check::lightmap_violations(path, file, length, scene).map(|_| ())
    });
    prop_assert!(largest <= image_allocation_allowed(bytes), "allocated {largest} bytes ({outcome})");
    Ok(())
}

/// A byte-level change to a file.
#[derive(Clone, Debug)]
enum Mutation {
    /// XOR a byte with a non-zero mask.
    Flip(Index, u8),
    /// Set a byte among the first 512 (headers, attribute tables, offsets).
    Head(usize, u8),
    /// Write a little-endian 32-bit number (a size, count or offset) at any position.
    Word(Index, u32),
    /// Cut the file there.
    Cut(Index),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let word = prop_oneof![
        prop::sample::select(vec![
            0u32,
            1,
            2,
            3,
            7,
            8,
            255,
            256,
            65535,
            65536,
            1 << 20,
            i32::MAX as u32,
            1 << 31,
            u32::MAX
        ]),
        any::<u32>(),
    ];
    prop_oneof![
        4 => (any::<Index>(), 1u8..).prop_map(|(i, m)| Mutation::Flip(i, m)),
        3 => (0usize..512, any::<u8>()).prop_map(|(i, v)| Mutation::Head(i, v)),
        2 => (any::<Index>(), word).prop_map(|(i, w)| Mutation::Word(i, w)),
        1 => any::<Index>().prop_map(Mutation::Cut),
    ]
}

fn mutated(mut bytes: Vec<u8>, mutations: &[Mutation]) -> Vec<u8> {
    for mutation in mutations {
        if bytes.is_empty() {
            break;
        }
        match *mutation {
            Mutation::Flip(ref at, mask) => {
                let at = at.index(bytes.len());
                bytes[at] ^= mask;
            }
            Mutation::Head(at, value) => {
                if at < bytes.len() {
                    bytes[at] = value;
                }
            }
            Mutation::Word(ref at, word) => {
                let at = at.index(bytes.len());
                let end = (at + 4).min(bytes.len());
                bytes[at..end].copy_from_slice(&word.to_le_bytes()[..end - at]);
            }
            Mutation::Cut(ref at) => bytes.truncate(at.index(bytes.len())),
        }
    }
    bytes
}

/// Applies JSON `edits` (as for the glTF chunk) to a report.
fn edited_report(edits: &[Edit]) -> Vec<u8> {
    let mut json: Value = serde_json::from_slice(&golden_report()).unwrap();
    apply(&mut json, edits);
    serde_json::to_vec_pretty(&json).unwrap()
}

proptest! {
    #![proptest_config(config(300))]

    #[test]
    fn mutated_environments_never_panic(seed in any::<Index>(), mutations in prop::collection::vec(mutation(), 1..8)) {
        let seeds = environment_seeds();
        let (bytes, name) = seed.get(&seeds);
        check_environment(&mutated(bytes.clone(), &mutations), name)?;
    }

    #[test]
    fn mutated_reports_never_panic(mutations in prop::collection::vec(mutation(), 1..8)) {
        check_report(&mutated(golden_report(), &mutations))?;
    }

    #[test]
    fn edited_reports_never_panic(edits in prop::collection::vec(edit(), 1..5)) {
        check_report(&edited_report(&edits))?;
    }

    #[test]
    fn mutated_lightmaps_never_panic(mutations in prop::collection::vec(mutation(), 1..8)) {
        let (scene, bytes) = lightmap_seed();
        check_lightmap(&scene, &mutated(bytes, &mutations))?;
    }
}

// ---------------------------------------------------------------------------------------------
// Named regressions: inputs that crashed or misbehaved, kept as they were found.

/// A case must fail with an error containing `expected`, in bounded memory.
fn assert_refused(bytes: &[u8], expected: &str) {
    let (outcome, largest) = import(bytes);
    assert!(outcome.contains(expected), "expected an error with '{expected}', got: {outcome}");
    assert!(largest <= LARGEST_ALLOWED, "allocated {largest} bytes");
}

#[test]
fn regression_glb_length_below_the_header_size() {
    // gltf's GLB reader subtracts 12 from the declared length: an overflow
    // panic in debug builds for a length under 12. bake reads the GLB itself.
    let mut bytes = fixture("sphere_on_ground.glb");
    for length in [0u32, 4, 11, 12, 19] {
        bytes[8..12].copy_from_slice(&length.to_le_bytes());
        assert_refused(&bytes, ".glb");
    }
}

#[test]
fn regression_sparse_offset_near_usize_max() {
    // A sparse accessor whose index offset is near 2^64: `offset + n·size`
    // wrapped around in release builds, passed the bounds check and panicked
    // on the slice. The sum is checked now.
    let (mut json, bin) = parts("sphere_on_ground.glb");
    json["bufferViews"].as_array_mut().unwrap().push(json!({ "buffer": 0, "byteOffset": 0, "byteLength": 64 }));
    let view = json["bufferViews"].as_array().unwrap().len() - 1;
    json["accessors"][0]["sparse"] = json!({
        "count": 2,
        "indices": { "bufferView": view, "byteOffset": u64::MAX - 3, "componentType": 5125 },
        "values": { "bufferView": view, "byteOffset": 0 },
    });
    assert_refused(&glb(&json, &bin), "sparse data runs past the end of its bufferView");
}

#[test]
fn regression_viewless_accessor_with_a_huge_count() {
    // No buffer view: the accessor is zeros of whatever count it declares.
    let (mut json, bin) = parts("sphere_on_ground.glb");
    json["accessors"][0].as_object_mut().unwrap().remove("bufferView");
    json["accessors"][0]["count"] = json!(u32::MAX);
    json["accessors"][0]["sparse"] =
        json!({ "count": 1, "indices": { "bufferView": 3, "componentType": 5125 }, "values": { "bufferView": 0 } });
    // The vertex budget refuses it before anything is read; within a budget
    // that admits it, the accessor's own check does.
    assert_refused(&glb(&json, &bin), "the scene's primitives read 4294968520 vertices");
    let (outcome, largest) = import_within(&glb(&json, &bin), u64::MAX / 4);
    let expected = "accessor 0: 4294967295 elements of 12 bytes with no bufferView";
    assert!(outcome.contains(expected) && largest <= LARGEST_ALLOWED, "{outcome}; {largest} bytes");
    // Just under the cap it is read (zeros and one sparse value), in bounded memory.
    json["accessors"][0]["count"] = json!((256 << 20) / 12);
    let (outcome, largest) = import_within(&glb(&json, &bin), u64::MAX / 4);
    eprintln!("a viewless accessor of 256 MiB: {outcome}; largest allocation {} MiB", largest >> 20);
    assert!(largest <= LARGEST_ALLOWED);
}

#[test]
fn regression_position_accessor_index_out_of_range() {
    // Found by `edited_json_never_panics` (seed 0, Add(+8) to a POSITION
    // index): gltf-json's primitive validation indexed `accessors[8]` of 8.
    let (mut json, bin) = parts("sphere_on_ground.glb");
    let accessors = json["accessors"].as_array().unwrap().len();
    json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(accessors);
    assert_refused(&glb(&json, &bin), "attributes.POSITION is accessor 8, but there are 8 accessors");
}

#[test]
fn regression_image_without_uri_or_buffer_view() {
    // Found by `edited_json_never_panics` (seed 1, Remove of an image's uri):
    // gltf's `Image::source` unwrapped the missing uri.
    let (mut json, bin) = parts("everything.glb");
    let images = json["images"].as_array_mut().unwrap();
    let with_uri = images.iter().position(|i| i.get("uri").is_some()).unwrap();
    images[with_uri].as_object_mut().unwrap().remove("uri");
    assert_refused(&glb(&json, &bin), &format!("images[{with_uri}] has neither a uri nor a bufferView"));
    // The same family: an image in a buffer view without its mimeType.
    let (mut json, bin) = parts("everything.glb");
    let images = json["images"].as_array_mut().unwrap();
    let in_view = images.iter().position(|i| i.get("bufferView").is_some()).unwrap();
    images[in_view].as_object_mut().unwrap().remove("mimeType");
    assert_refused(&glb(&json, &bin), &format!("images[{in_view}] is in a bufferView but has no mimeType"));
}
