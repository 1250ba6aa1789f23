//! The exported files, read back as an engine or a viewer would: everything
//! in the input survives (nodes, meshes, materials, animations, cameras,
//! skins, extras, unknown extensions, names, order); the default material is
//! the unlit baked one and the input's PBR material is one variant away with
//! a `MOZ_lightmap` of linear irradiance over its `intensity` that decodes to
//! the EXR (`--material engine` swaps the two); the `.gltf` form holds the same
//! scene; `--keep-uv1` bakes into a valid TEXCOORD_1 and otherwise says why
//! not; no output ever replaces a file of an input.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Output;

use crate::common::{self, fixture, read_exr};
use bake::asset::{SourceAsset, accessor};
use bake::report::Report;
use serde_json::{Value, json};

/// Runs a tiny bake of `input` under the sun-and-sky fixture into `out`.
fn bake(input: &Path, out: &Path, extra: &[&str]) -> Output {
    common::tiny_bake(input, out, extra)
}

fn bake_ok(input: &Path, out: &Path, extra: &[&str]) {
    let output = bake(input, out, extra);
    assert!(output.status.success(), "bake {}: {}", input.display(), String::from_utf8_lossy(&output.stderr));
}

fn report(out: &Path) -> Report {
    serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap()
}

/// Accessor `index` of `asset` as floats.
fn floats(asset: &SourceAsset, index: usize) -> Vec<f32> {
    accessor::read_floats(asset, &asset.document.accessors().nth(index).unwrap()).unwrap()
}

/// The accessor a primitive's attribute names, if any.
fn attribute(json: &Value, mesh: usize, primitive: usize, name: &str) -> Option<usize> {
    json["meshes"][mesh]["primitives"][primitive]["attributes"][name].as_u64().map(|i| i as usize)
}

/// Triangles of a primitive in UV set `set` (its indices, or none for a non-indexed one).
fn uv_triangles(asset: &SourceAsset, mesh: usize, primitive: usize, set: &str) -> Vec<[[f32; 2]; 3]> {
    let uv = floats(asset, attribute(&asset.json, mesh, primitive, set).unwrap());
    let indices = asset.json["meshes"][mesh]["primitives"][primitive]["indices"].as_u64().unwrap() as usize;
    let indices = accessor::read_indices(asset, &asset.document.accessors().nth(indices).unwrap()).unwrap();
    indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| [uv[2 * t[k] as usize], uv[2 * t[k] as usize + 1]])).collect()
}

/// Whether two UV triangles overlap with positive area (separating axis test).
fn overlap(a: [[f32; 2]; 3], b: [[f32; 2]; 3]) -> bool {
    const EPS: f32 = 1e-6;
    for tri in [a, b] {
        for k in 0..3 {
            let (p, q) = (tri[k], tri[(k + 1) % 3]);
            let axis = [p[1] - q[1], q[0] - p[0]];
            let project = |t: [[f32; 2]; 3]| {
                let d = t.map(|v| v[0] * axis[0] + v[1] * axis[1]);
                (d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]))
            };
            let ((a0, a1), (b0, b1)) = (project(a), project(b));
            if a1 <= b0 + EPS || b1 <= a0 + EPS {
                return false;
            }
        }
    }
    true
}

/// The input's JSON object with `key` removed (for "equal except for what bake adds").
fn without(value: &Value, pointer: &str, key: &str) -> Value {
    let mut value = value.clone();
    if let Some(object) = value.pointer_mut(pointer).and_then(Value::as_object_mut) {
        object.remove(key);
        if object.is_empty() && !pointer.is_empty() {
            let (parent, child) = pointer.rsplit_once('/').unwrap();
            value
                .pointer_mut(if parent.is_empty() { "" } else { parent })
                .unwrap()
                .as_object_mut()
                .unwrap()
                .remove(child);
        }
    }
    value
}

#[test]
fn everything_in_the_input_survives() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("everything.glb");
    bake_ok(&input, dir.path(), &[]);
    let before = SourceAsset::load(&input).unwrap();
    let after = SourceAsset::load(&dir.path().join("everything.glb")).unwrap();
    let (a, b) = (&before.json, &after.json);
    let count = |json: &Value, key: &str| json[key].as_array().map_or(0, Vec::len);

    // The root: asset, extras, extensions, extensions used and required.
    assert_eq!(b["asset"], a["asset"]);
    assert_eq!(b["extras"], a["extras"]);
    assert_eq!(b["extensions"]["ACME_marker"], a["extensions"]["ACME_marker"]);
    assert_eq!(b["scene"], a["scene"]);
    assert_eq!(b["scenes"], a["scenes"]);
    let used: Vec<&Value> = b["extensionsUsed"].as_array().unwrap().iter().collect();
    for name in a["extensionsUsed"].as_array().unwrap() {
        assert!(used.contains(&name), "{name} is no longer in extensionsUsed");
    }
    for name in ["KHR_materials_unlit", "KHR_materials_variants", "MOZ_lightmap"] {
        assert!(used.contains(&&json!(name)), "{name} is not in extensionsUsed");
    }
    assert_eq!(b.get("extensionsRequired"), a.get("extensionsRequired"), "bake requires nothing new");

    // Nodes: same count and order, every field kept; a baked node may point at a copy of its mesh,
    // and gains `extras.bake`, naming its KTX2 lightmap (tests/it/lightmap_ktx2.rs).
    assert_eq!(count(b, "nodes"), count(a, "nodes"));
    let input_meshes = count(a, "meshes");
    for (i, (x, y)) in a["nodes"].as_array().unwrap().iter().zip(b["nodes"].as_array().unwrap()).enumerate() {
        assert_eq!(without(&without(y, "", "mesh"), "/extras", "bake"), without(x, "", "mesh"), "node {i}");
        if let Some(mesh) = x["mesh"].as_u64() {
            let out = y["mesh"].as_u64().unwrap();
            assert!(out == mesh || out as usize >= input_meshes, "node {i} draws mesh {out}");
            assert!(
                b["meshes"][out as usize]["name"]
                    .as_str()
                    .unwrap()
                    .starts_with(a["meshes"][mesh as usize]["name"].as_str().unwrap())
            );
        }
    }
    // Meshes: every input mesh at its index with its name and extras; what is not baked is untouched.
    for (m, mesh) in a["meshes"].as_array().unwrap().iter().enumerate() {
        assert_eq!(b["meshes"][m]["name"], mesh["name"]);
        assert_eq!(b["meshes"][m]["extras"], mesh["extras"]);
    }
    assert_eq!(b["meshes"][2], a["meshes"][2], "the skinned node's mesh is untouched");
    assert_eq!(b["nodes"][4]["mesh"], 2);
    assert_eq!(b["meshes"][0]["primitives"][1], a["meshes"][0]["primitives"][1], "the points primitive is untouched");
    // Materials keep their indices; one only gains MOZ_lightmap, in place.
    for (m, material) in a["materials"].as_array().unwrap().iter().enumerate() {
        assert_eq!(without(&b["materials"][m], "/extensions", "MOZ_lightmap"), *material, "material {m}");
    }
    assert_eq!(b["materials"][1], a["materials"][1], "material 1 is drawn by the skinned mesh too: untouched");
    // Animations, cameras, skins, samplers and textures (the input's, at their indices).
    for key in ["animations", "cameras", "skins"] {
        assert_eq!(b[key], a[key], "{key}");
    }
    assert_eq!(b["samplers"][0], a["samplers"][0]);
    for (t, texture) in a["textures"].as_array().unwrap().iter().enumerate() {
        assert_eq!(b["textures"][t], *texture);
        assert_eq!(b["images"][t]["name"], a["images"][t]["name"]);
    }
    // The data behind animations, skins and untouched primitives, accessor for accessor.
    for index in 0..count(a, "accessors") {
        assert_eq!(b["accessors"][index], a["accessors"][index], "accessor {index}");
        assert_eq!(floats(&after, index), floats(&before, index), "accessor {index} data");
    }
    // The data-URI image is embedded, byte for byte.
    assert_eq!(after.image_bytes(1).unwrap().0, before.image_bytes(1).unwrap().0);

    // Baked primitives: TEXCOORD_1 is the lightmap; the input's TEXCOORD_1 moved to TEXCOORD_2 with
    // every other attribute kept, and the material's occlusion map follows it.
    let ground: Vec<&String> = b["meshes"][0]["primitives"][0]["attributes"].as_object().unwrap().keys().collect();
    assert_eq!(ground, ["COLOR_0", "NORMAL", "POSITION", "TANGENT", "TEXCOORD_0", "TEXCOORD_1", "TEXCOORD_2"]);
    let skinned_copy = b["nodes"][3]["mesh"].as_u64().unwrap() as usize;
    for name in ["JOINTS_0", "WEIGHTS_0", "TEXCOORD_2"] {
        assert!(attribute(b, skinned_copy, 0, name).is_some(), "the static flag lost {name}");
    }
    let vertices = |asset: &SourceAsset, mesh: usize, uv1: &str| -> Vec<Vec<u32>> {
        let names = ["POSITION", "TEXCOORD_0", uv1];
        let data: Vec<Vec<f32>> =
            names.iter().map(|n| floats(asset, attribute(&asset.json, mesh, 0, n).unwrap())).collect();
        (0..data[0].len() / 3)
            .map(|v| [&data[0][3 * v..3 * v + 3], &data[1][2 * v..2 * v + 2], &data[2][2 * v..2 * v + 2]].concat())
            .map(|v| v.iter().map(|c| c.to_bits()).collect())
            .collect()
    };
    let original: std::collections::BTreeSet<Vec<u32>> = vertices(&before, 1, "TEXCOORD_1").into_iter().collect();
    for vertex in vertices(&after, 1, "TEXCOORD_2") {
        assert!(original.contains(&vertex), "crate vertex {vertex:?} is not an input vertex");
    }
    let mappings =
        |mesh: usize| b["meshes"][mesh]["primitives"][0]["extensions"]["KHR_materials_variants"]["mappings"].clone();
    let crate_pbr = mappings(1)[1]["material"].as_u64().unwrap() as usize;
    assert_eq!(b["materials"][crate_pbr]["occlusionTexture"]["texCoord"], 2);
    assert_eq!(b["materials"][crate_pbr]["extensions"]["ACME_marker"], a["materials"][1]["extensions"]["ACME_marker"]);

    // Viewer form by default, engine form one variant away.
    let variants = b["extensions"]["KHR_materials_variants"]["variants"].clone();
    assert_eq!(variants, json!([{ "name": "baked" }, { "name": "pbr+lightmap" }]));
    let mut baked = 0;
    for (m, mesh) in b["meshes"].as_array().unwrap().iter().enumerate() {
        for (p, primitive) in mesh["primitives"].as_array().unwrap().iter().enumerate() {
            let Some(mappings) = primitive.pointer("/extensions/KHR_materials_variants/mappings") else { continue };
            baked += 1;
            let default = &b["materials"][primitive["material"].as_u64().unwrap() as usize];
            assert!(default["extensions"].get("KHR_materials_unlit").is_some(), "mesh {m} primitive {p}");
            assert_eq!(default["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"], 1);
            assert_eq!(mappings[0], json!({ "material": primitive["material"], "variants": [0] }));
            let pbr = &b["materials"][mappings[1]["material"].as_u64().unwrap() as usize];
            assert_eq!(mappings[1]["variants"], json!([1]));
            assert_eq!(pbr["extensions"]["MOZ_lightmap"]["texCoord"], 1);
            assert!(pbr["extensions"].get("KHR_materials_unlit").is_none());
        }
    }
    assert_eq!(baked, 5, "ground, two crates, the static flag and the orb");

    // The two crates have lightmap regions of their own.
    let (crate_a, crate_b) =
        (b["nodes"][1]["mesh"].as_u64().unwrap() as usize, b["nodes"][2]["mesh"].as_u64().unwrap() as usize);
    assert_ne!(crate_a, crate_b);
    let (ta, tb) = (uv_triangles(&after, crate_a, 0, "TEXCOORD_1"), uv_triangles(&after, crate_b, 0, "TEXCOORD_1"));
    let overlapping = ta.iter().flat_map(|x| tb.iter().map(move |y| (x, y))).filter(|(x, y)| overlap(**x, **y)).count();
    eprintln!(
        "{} nodes, {} → {} meshes, {} → {} materials, {} → {} accessors; crates: {} and {} triangles, {overlapping} overlapping",
        count(b, "nodes"),
        input_meshes,
        count(b, "meshes"),
        count(a, "materials"),
        count(b, "materials"),
        count(a, "accessors"),
        count(b, "accessors"),
        ta.len(),
        tb.len()
    );
    assert_eq!(overlapping, 0);
}

/// The PNG chunk types of `png`, in order.
fn png_chunks(png: &[u8]) -> Vec<String> {
    let mut chunks = Vec::new();
    let mut at = 8;
    while at + 8 <= png.len() {
        let length = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
        chunks.push(String::from_utf8_lossy(&png[at + 4..at + 8]).into_owned());
        at += 12 + length;
    }
    chunks
}

#[test]
fn the_moz_lightmap_is_linear_irradiance_over_its_intensity() {
    let dir = tempfile::tempdir().unwrap();
    // Under the sun, L_lm reaches far above 1.
    bake_ok(&fixture("sphere_on_ground.glb"), dir.path(), &[]);
    let asset = SourceAsset::load(&dir.path().join("sphere_on_ground.glb")).unwrap();
    let json = &asset.json;
    let lightmaps: Vec<&Value> =
        json["materials"].as_array().unwrap().iter().filter_map(|m| m.pointer("/extensions/MOZ_lightmap")).collect();
    assert_eq!(lightmaps.len(), 2, "both input materials carry the lightmap");
    assert!(lightmaps.iter().all(|l| *l == lightmaps[0]));
    assert_eq!(lightmaps[0]["texCoord"], 1);
    let intensity = lightmaps[0]["intensity"].as_f64().unwrap();
    let texture = &json["textures"][lightmaps[0]["index"].as_u64().unwrap() as usize];
    let extras = &texture["extras"]["bake"];
    assert_eq!((&extras["encoding"], &extras["scale"]), (&json!("linear"), &json!(intensity)));
    assert_eq!(extras["hdr"], "sphere_on_ground.lightmap0.exr");
    let (png, mime) = asset.image_bytes(texture["source"].as_u64().unwrap() as usize).unwrap();
    assert_eq!(mime.as_deref(), Some("image/png"));
    let chunks = png_chunks(&png);
    assert!(
        !chunks.iter().any(|c| c == "sRGB" || c == "gAMA" || c == "iCCP"),
        "raw codes, no colour space: {chunks:?}"
    );
    let image = image::load_from_memory(&png).unwrap();
    // RGB: an RGBM file (RGBA) or any alpha a reader would have to know about fails here.
    assert_eq!(image.color(), image::ColorType::Rgb8);
    let codes = image.to_rgb8();

    let (width, hdr) = read_exr(&dir.path().join("sphere_on_ground.lightmap0.exr"));
    assert_eq!((codes.width() as usize, hdr.len()), (width, codes.len() / 3));
    let peak = std::f64::consts::PI * hdr.iter().flatten().copied().fold(0.0f32, f32::max) as f64;
    assert!(peak > std::f64::consts::PI, "the sun makes L_lm exceed 1 ({peak})");
    assert!(intensity >= peak && intensity <= peak * 1.001, "intensity {intensity} for a peak E of {peak}");
    let (mut worst_steps, mut lit) = (0.0f64, 0);
    let step = intensity / 255.0;
    for (i, (pixel, value)) in codes.pixels().zip(&hdr).enumerate() {
        for c in 0..3 {
            // As the readers shade it: E = intensity · code/255, irradiance; L_lm = E/π.
            let e = intensity * pixel[c] as f64 / 255.0;
            let error = (e - std::f64::consts::PI * value[c] as f64).abs();
            assert!(
                error <= step / 2.0 * (1.0 + 1e-6),
                "texel {i}: L_lm {value:?} is E {:?} but the PNG holds {pixel:?}, E {e}",
                value.map(|v| std::f64::consts::PI * v as f64)
            );
            worst_steps = worst_steps.max(error / step);
        }
        lit += usize::from(value.iter().any(|&v| v > 0.0));
    }
    eprintln!(
        "{width}² MOZ_lightmap, intensity {intensity} (peak E {peak:.4}), {lit} non-black texels: worst error {:.3} \
         of a code step",
        worst_steps
    );
}

#[test]
fn the_engine_material_draws_the_pbr_form_and_keeps_the_preview_a_variant_away() {
    let dir = tempfile::tempdir().unwrap();
    let (preview, engine) = (dir.path().join("preview"), dir.path().join("engine"));
    bake_ok(&fixture("sphere_on_ground.glb"), &preview, &[]);
    bake_ok(&fixture("sphere_on_ground.glb"), &engine, &["--material", "engine"]);
    let load = |out: &Path| SourceAsset::load(&out.join("sphere_on_ground.glb")).unwrap().json;
    let (preview_json, engine_json) = (load(&preview), load(&engine));
    for mesh in 0..2 {
        let pointer = format!("/meshes/{mesh}/primitives/0");
        let (p, e) = (preview_json.pointer(&pointer).unwrap(), engine_json.pointer(&pointer).unwrap());
        let mappings = &p["extensions"]["KHR_materials_variants"]["mappings"];
        // Variant 0 is `baked`, 1 `pbr+lightmap`, in both files.
        let (baked, pbr) = (&mappings[0]["material"], &mappings[1]["material"]);
        assert_eq!(mappings[0]["variants"], json!([0]));
        assert_eq!(mappings[1]["variants"], json!([1]));
        assert_eq!((&p["material"], &e["material"]), (baked, pbr), "{p} / {e}");
        assert_eq!(e["extensions"], p["extensions"], "the same mappings");
        let material = &engine_json["materials"][pbr.as_u64().unwrap() as usize];
        assert!(material.pointer("/extensions/MOZ_lightmap").is_some(), "{material}");
        assert!(material.pointer("/extensions/KHR_materials_unlit").is_none(), "{material}");
    }
    let mut swapped = engine_json.clone();
    for mesh in 0..2 {
        let primitive = &mut swapped["meshes"][mesh]["primitives"][0];
        primitive["material"] = primitive["extensions"]["KHR_materials_variants"]["mappings"][0]["material"].clone();
    }
    assert_eq!(swapped, preview_json, "nothing else differs");
    assert_eq!(
        std::fs::read(preview.join("sphere_on_ground.lightmap0.exr")).unwrap(),
        std::fs::read(engine.join("sphere_on_ground.lightmap0.exr")).unwrap()
    );
}

/// Every file in `dir` but report.json, by name.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap() != "report.json")
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect()
}

#[test]
fn the_gltf_form_holds_the_same_scene_in_separate_files() {
    let dir = tempfile::tempdir().unwrap();
    let (glb_dir, gltf_dir) = (dir.path().join("glb"), dir.path().join("gltf"));
    bake_ok(&fixture("everything.glb"), &glb_dir, &[]);
    bake_ok(&fixture("everything.glb"), &gltf_dir, &["--format", "gltf"]);
    let written = files(&gltf_dir);
    let names: Vec<&str> = written.keys().map(String::as_str).collect();
    assert_eq!(
        names,
        [
            "everything.baked0.png",
            "everything.bin",
            "everything.gltf",
            "everything.image1.png",
            "everything.lightmap0.exr",
            "everything.lightmap0.ktx2",
            "everything.lightmap0.png",
        ]
    );
    let outputs: Vec<String> = report(&gltf_dir).scenes[0]
        .outputs
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(outputs.len(), 7, "{outputs:?}");

    // Everything resolves through its URI, as a loader reads it.
    let (document, buffers, images) = gltf::import(gltf_dir.join("everything.gltf")).expect("the .gltf loads");
    assert_eq!((buffers.len(), images.len()), (1, 4));
    assert_eq!(document.images().filter(|i| matches!(i.source(), gltf::image::Source::Uri { .. })).count(), 3);

    // The same scene as the .glb: the same JSON but for where images live, and the same
    // binary data, the .glb's images appended after it.
    let glb = SourceAsset::load(&glb_dir.join("everything.glb")).unwrap();
    let gltf = SourceAsset::load(&gltf_dir.join("everything.gltf")).unwrap();
    for key in ["nodes", "meshes", "materials", "accessors", "textures", "animations", "skins", "extensions"] {
        assert_eq!(gltf.json[key], glb.json[key], "{key}");
    }
    let bin = &written["everything.bin"];
    assert_eq!(&glb.buffers[0][..bin.len()], &bin[..]);
    assert_eq!(written["everything.image1.png"], glb.image_bytes(1).unwrap().0);
    for lightmap in ["everything.lightmap0.exr", "everything.lightmap0.ktx2"] {
        assert_eq!(written[lightmap], std::fs::read(glb_dir.join(lightmap)).unwrap(), "{lightmap}");
    }
}

#[test]
fn keep_uv1_bakes_into_a_valid_uv_set() {
    let dir = tempfile::tempdir().unwrap();
    // A baked file has a valid TEXCOORD_1 on every primitive: bake it again into it.
    bake_ok(&fixture("sphere_on_ground.glb"), &dir.path().join("first"), &[]);
    let input = dir.path().join("rebake.glb");
    std::fs::copy(dir.path().join("first/sphere_on_ground.glb"), &input).unwrap();
    bake_ok(&input, &dir.path().join("second"), &["--keep-uv1"]);
    let scene = &report(&dir.path().join("second")).scenes[0];
    assert_eq!(scene.atlas.unwrapper, "input TEXCOORD_1");
    assert!(!scene.notices.iter().any(|n| n.contains("TEXCOORD")), "{:?}", scene.notices);
    let before = SourceAsset::load(&input).unwrap();
    let after = SourceAsset::load(&dir.path().join("second/rebake.glb")).unwrap();
    for mesh in 0..2 {
        let uv = |asset: &SourceAsset| floats(asset, attribute(&asset.json, mesh, 0, "TEXCOORD_1").unwrap());
        assert_eq!(uv(&after), uv(&before), "mesh {mesh}: the lightmap lies in the input's TEXCOORD_1");
        assert!(attribute(&after.json, mesh, 0, "TEXCOORD_2").is_none(), "nothing moved aside");
        // Baking a baked file again keeps one pair of variants, the input's PBR material in the second.
        let mappings = &after.json["meshes"][mesh]["primitives"][0]["extensions"]["KHR_materials_variants"]["mappings"];
        assert_eq!(mappings.as_array().unwrap().len(), 2, "{mappings}");
        let pbr = &after.json["materials"][mappings[1]["material"].as_u64().unwrap() as usize];
        assert_eq!(pbr["name"], ["ground", "sphere"][mesh]);
        assert!(pbr["extensions"].get("KHR_materials_unlit").is_none());
    }
    assert_eq!(
        after.json["extensions"]["KHR_materials_variants"]["variants"],
        json!([{ "name": "baked" }, { "name": "pbr+lightmap" }])
    );
    eprintln!("kept: {:?}", scene.atlas);
}

#[test]
fn keep_uv1_falls_back_with_a_notice_naming_the_primitive_and_the_check() {
    let dir = tempfile::tempdir().unwrap();
    // The orb of `everything` has no TEXCOORD_1.
    bake_ok(&fixture("everything.glb"), &dir.path().join("missing"), &["--keep-uv1"]);
    let scene = &report(&dir.path().join("missing")).scenes[0];
    assert_ne!(scene.atlas.unwrapper, "input TEXCOORD_1");
    let notice = scene.notices.iter().find(|n| n.starts_with("--keep-uv1")).expect("a notice");
    assert!(notice.contains("mesh 3 primitive 0 on node 7 has no TEXCOORD_1"), "{notice}");

    // Two nodes drawing one mesh share its TEXCOORD_1: their lightmaps would overlap.
    bake_ok(&fixture("sphere_on_ground.glb"), &dir.path().join("first"), &[]);
    let glb = std::fs::read(dir.path().join("first/sphere_on_ground.glb")).unwrap();
    let parsed = gltf::binary::Glb::from_slice(&glb).unwrap();
    let mut json: Value = serde_json::from_slice(&parsed.json).unwrap();
    json["nodes"][1]["mesh"] = json!(0);
    let input = dir.path().join("twice.glb");
    std::fs::write(&input, bake::export::glb::encode(&serde_json::to_vec(&json).unwrap(), &parsed.bin.unwrap()))
        .unwrap();
    bake_ok(&input, &dir.path().join("overlap"), &["--keep-uv1"]);
    let scene = &report(&dir.path().join("overlap")).scenes[0];
    let notice = scene.notices.iter().find(|n| n.starts_with("--keep-uv1")).expect("a notice");
    assert!(
        notice.contains("mesh 0 primitive 0 on node 0 overlaps mesh 0 primitive 0 on node 1 in UV space"),
        "{notice}"
    );
    eprintln!("{notice}");
}

#[test]
fn outputs_never_replace_a_file_of_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("scene");
    bake_ok(&fixture("everything.glb"), &folder, &["--format", "gltf"]);
    let input = folder.join("everything.gltf");
    let before = files(&folder);

    // A .gltf output into the input's own folder would replace the input and its .bin.
    let output = bake(&input, &folder, &["--format", "gltf"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("would replace a file of an input"), "{stderr}");
    assert_eq!(files(&folder), before, "nothing in the folder changed");
    assert!(
        !std::fs::read_dir(&folder).unwrap().any(|e| e.unwrap().file_name().to_string_lossy().starts_with(".bake"))
    );

    // A .glb output beside it replaces none of its files.
    bake_ok(&input, &folder, &[]);
    let after = files(&folder);
    for (name, bytes) in &before {
        // The HDR lightmaps are this bake's, of the baked file.
        if name != "everything.lightmap0.exr" && name != "everything.lightmap0.ktx2" {
            assert_eq!(&after[name], bytes, "{name} changed");
        }
    }
    assert!(after.contains_key("everything.glb"));
}

/// A floor with a box on it, `offset` metres from the world origin.
fn floor_and_box(offset: glam::Vec3) -> Vec<u8> {
    use bake::fixtures::{MeshData, Placement, SceneBuilder};
    let mut builder = SceneBuilder::new();
    let grey = [0.6, 0.6, 0.6, 1.0];
    builder.object("floor", &MeshData::plane(4.0, 4.0, 4), grey, [0.0; 3], Placement::at(offset));
    let above = offset + glam::Vec3::new(0.5, 0.5, 0.5);
    builder.object("box", &MeshData::cuboid([1.0; 3]), grey, [0.0; 3], Placement::at(above));
    builder.to_glb()
}

#[test]
fn a_scene_far_from_the_origin_is_written_back_where_it_was() {
    // The bake works relative to a scene origin near the geometry; the output
    // keeps the input's node transforms and vertex data bit for bit, and the
    // light does not depend on where the scene sits. Baked in f32 world
    // coordinates the box came out 1.0% darker at 1e5 m; now the means agree
    // to 5 digits.
    let dir = tempfile::tempdir().unwrap();
    let (far, home) = (dir.path().join("far.glb"), dir.path().join("home.glb"));
    std::fs::write(&far, floor_and_box(glam::Vec3::new(1e5 + 0.3, 0.2, -1e5 - 0.7))).unwrap();
    std::fs::write(&home, floor_and_box(glam::Vec3::new(0.3, 0.2, -0.7))).unwrap();
    bake_ok(&far, &dir.path().join("far"), &[]);
    bake_ok(&home, &dir.path().join("home"), &[]);

    let before = SourceAsset::load(&far).unwrap();
    let after = SourceAsset::load(&dir.path().join("far").join("far.glb")).unwrap();
    for (i, node) in before.json["nodes"].as_array().unwrap().iter().enumerate() {
        assert_eq!(after.json["nodes"][i]["translation"], node["translation"], "node {i}");
    }
    for mesh in 0..2 {
        let out_mesh = after.json["nodes"][mesh]["mesh"].as_u64().unwrap() as usize;
        let bits = |asset: &SourceAsset, mesh: usize| -> std::collections::BTreeSet<[u32; 3]> {
            let p = floats(asset, attribute(&asset.json, mesh, 0, "POSITION").unwrap());
            p.chunks_exact(3).map(|v| [v[0].to_bits(), v[1].to_bits(), v[2].to_bits()]).collect()
        };
        assert_eq!(bits(&after, out_mesh), bits(&before, mesh), "mesh {mesh}: POSITION values changed");
    }

    let (far, home) = (report(&dir.path().join("far")), report(&dir.path().join("home")));
    for (f, h) in far.scenes[0].energy.iter().zip(&home.scenes[0].energy) {
        let (a, b) = (f.stats.mean_lightmap[0], h.stats.mean_lightmap[0]);
        eprintln!("{}: mean L_lm {a:.5} at 1e5 m, {b:.5} at the origin", f.name);
        assert!((a / b - 1.0).abs() < 0.002, "{}: mean L_lm {a} far away, {b} at the origin", f.name);
    }
}

#[test]
fn an_accessor_without_a_buffer_view_is_read_as_zeros() {
    // glTF 2.0: an accessor with neither a bufferView nor sparse data is
    // all zeros. A triangle whose TEXCOORD_0 is such an accessor bakes, and
    // the accessor is carried through as it was.
    let dir = tempfile::tempdir().unwrap();
    let positions: Vec<u8> =
        [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    use base64::Engine as _;
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&positions)
    );
    let gltf = json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}}]}],
        "buffers": [{"byteLength": 36, "uri": uri}], "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, -1], "max": [1, 0, 0]},
            {"componentType": 5126, "count": 3, "type": "VEC2"}
        ]
    });
    let input = dir.path().join("viewless.gltf");
    std::fs::write(&input, serde_json::to_vec(&gltf).unwrap()).unwrap();
    let out = dir.path().join("out");
    bake_ok(&input, &out, &[]);
    let baked = SourceAsset::load(&out.join("viewless.glb")).unwrap();
    let texcoord = baked.document.meshes().next().unwrap().primitives().next().unwrap();
    let uv0 = texcoord.get(&gltf::Semantic::TexCoords(0)).expect("TEXCOORD_0 carried through");
    assert_eq!(accessor::read_floats(&baked, &uv0).unwrap(), vec![0.0; 6]);
}
