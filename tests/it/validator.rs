//! Every fixture scene bakes into a file the Khronos glTF validator accepts
//! with zero errors (warnings are allowed, and printed), in both output
//! forms. The validator is the npm package `gltf-validator`, installed by
//! `pipeline/setup.sh` and run through `pipeline/validate.mjs`; without it
//! these tests fail, they never skip.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common;

use bake::fixtures::{MeshData, Placement, SceneBuilder};

/// Tiny bakes: what is checked here is the file, not the light.
fn bake(input: &Path, out: &Path, extra: &[&str]) {
    bake_all(&[input.to_path_buf()], out, extra);
}

/// `inputs` baked in one run, as a build step bakes a folder (one start-up).
fn bake_all(inputs: &[PathBuf], out: &Path, extra: &[&str]) {
    let paths: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let output = common::tiny_bake_all(&paths, out, extra);
    assert!(output.status.success(), "bake {inputs:?}: {}", String::from_utf8_lossy(&output.stderr));
}

/// The stem of `file`'s name, which names its outputs.
fn stem(file: &Path) -> String {
    file.file_stem().unwrap().to_string_lossy().into_owned()
}

/// The validator's report on `file`: (errors, warnings, every message as one line).
fn validate(file: &Path) -> (u64, u64, Vec<String>) {
    let script = common::repo("pipeline/validate.mjs");
    let output =
        Command::new("node").arg(&script).arg(file).output().unwrap_or_else(|e| {
            panic!("cannot run node ({e}): the glTF validator needs Node.js; run ./pipeline/setup.sh")
        });
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap_or_else(|_| {
        panic!(
            "the glTF validator gave no report on {} (run ./pipeline/setup.sh to install it): {}",
            file.display(),
            String::from_utf8_lossy(&output.stderr)
        )
    });
    let issues = &report["issues"];
    let messages = issues["messages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            format!(
                "{} {} at {}: {}",
                ["error", "warning", "info", "hint"][m["severity"].as_u64().unwrap() as usize],
                m["code"],
                m["pointer"],
                m["message"]
            )
        })
        .collect();
    (issues["numErrors"].as_u64().unwrap(), issues["numWarnings"].as_u64().unwrap(), messages)
}

/// Validates `file`, prints its errors and warnings, and fails on any error.
fn assert_valid(file: &Path) {
    let (errors, warnings, messages) = validate(file);
    let name = file.display();
    eprintln!("{name}: {errors} errors, {warnings} warnings, {} messages", messages.len());
    for message in messages.iter().filter(|m| !m.starts_with("info") && !m.starts_with("hint")) {
        eprintln!("  {message}");
    }
    assert_eq!(errors, 0, "{name} has validation errors:\n{}", messages.join("\n"));
}

fn fixture_scenes() -> Vec<PathBuf> {
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(common::repo("fixtures"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "glb" || e == "gltf"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 3, "fixtures/ holds {} scenes", scenes.len());
    scenes
}

#[test]
fn every_fixture_and_its_bake_pass_the_validator() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = fixture_scenes();
    bake_all(&inputs, dir.path(), &[]);
    for input in &inputs {
        assert_valid(input);
        assert_valid(&dir.path().join(format!("{}.glb", stem(input))));
    }
}

#[test]
fn the_gltf_form_passes_the_validator() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = fixture_scenes();
    bake_all(&inputs, dir.path(), &["--format", "gltf"]);
    for input in &inputs {
        // The validator reads the .bin and the images through their URIs.
        assert_valid(&dir.path().join(format!("{}.gltf", stem(input))));
    }
}

#[test]
fn the_engine_material_form_passes_the_validator() {
    // The PBR + MOZ_lightmap material as the default, the unlit preview a variant away.
    let dir = tempfile::tempdir().unwrap();
    let stems = ["everything", "sphere_on_ground"];
    bake_all(&stems.map(|stem| common::fixture(&format!("{stem}.glb"))), dir.path(), &["--material", "engine"]);
    for stem in stems {
        assert_valid(&dir.path().join(format!("{stem}.glb")));
    }
}

#[test]
fn a_primitive_without_texcoord_0_gets_a_valid_uv_numbering() {
    // glTF numbers texture coordinate sets from 0 without gaps: TEXCOORD_1 alone is an error.
    let dir = tempfile::tempdir().unwrap();
    let mut sphere = MeshData::sphere(1.0, 12, 6);
    sphere.uv0.clear();
    let mut scene = SceneBuilder::new();
    scene.object("bare", &sphere, [0.8, 0.8, 0.8, 1.0], [0.0; 3], Placement::default());
    let input = dir.path().join("bare.glb");
    std::fs::write(&input, scene.to_glb()).unwrap();
    bake(&input, &dir.path().join("out"), &[]);
    let output = dir.path().join("out/bare.glb");
    assert_valid(&output);
    let gltf = gltf::Gltf::open(&output).unwrap();
    let primitive = gltf.meshes().next().unwrap().primitives().next().unwrap();
    let (uv0, uv1) = (primitive.get(&gltf::Semantic::TexCoords(0)), primitive.get(&gltf::Semantic::TexCoords(1)));
    assert_eq!(uv0.unwrap().index(), uv1.unwrap().index(), "TEXCOORD_0 is the lightmap UVs too");
}

#[test]
fn the_validator_finds_errors() {
    // The check above can fail: a file with a dangling accessor index is an error.
    let dir = tempfile::tempdir().unwrap();
    let broken = dir.path().join("broken.gltf");
    std::fs::write(&broken, r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":7}}]}]}"#)
        .unwrap();
    let (errors, _, messages) = validate(&broken);
    assert!(errors > 0, "{messages:?}");
}

#[test]
fn gpu_instances_become_child_nodes_each_with_its_own_lightmap_uvs() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(6.0, 6.0, 1), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    let cube = scene.mesh("box", &MeshData::cuboid([0.6, 0.6, 0.6]), None);
    let turned = glam::Quat::from_rotation_y(0.8);
    let instances = [
        Placement::at(glam::Vec3::new(-1.4, 0.3, 0.0)),
        Placement::at(glam::Vec3::new(0.0, 0.3, 0.6)).rotated(turned),
        Placement::at(glam::Vec3::new(1.5, 0.45, -0.2)).scaled(glam::Vec3::splat(1.5)),
    ];
    scene.instanced_node("boxes", cube, Placement::at(glam::Vec3::new(0.3, 0.0, -0.4)), &instances);
    // An exporter without a fallback marks the extension required.
    let glb = scene.to_glb();
    let parsed = gltf::binary::Glb::from_slice(&glb).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&parsed.json).unwrap();
    json["extensionsRequired"] = serde_json::json!(["EXT_mesh_gpu_instancing"]);
    let bin = parsed.bin.unwrap().into_owned();
    let input = dir.path().join("boxes.glb");
    std::fs::write(&input, bake::export::glb::encode(&serde_json::to_vec(&json).unwrap(), &bin)).unwrap();
    assert_valid(&input);

    bake(&input, &dir.path().join("out"), &[]);
    let output = dir.path().join("out/boxes.glb");
    assert_valid(&output);
    let (document, buffers, _) = gltf::import(&output).unwrap();
    let out: serde_json::Value =
        serde_json::from_slice(&gltf::binary::Glb::from_slice(&std::fs::read(&output).unwrap()).unwrap().json).unwrap();
    for list in ["extensionsUsed", "extensionsRequired"] {
        let names = out.get(list).and_then(|l| l.as_array()).cloned().unwrap_or_default();
        assert!(!names.iter().any(|n| n == "EXT_mesh_gpu_instancing"), "{list}: {names:?}");
    }
    let node = &out["nodes"][1];
    assert!(node.get("mesh").is_none() && node.get("extensions").is_none() && node.get("extras").is_none(), "{node}");
    let parent = document.nodes().nth(1).unwrap().transform().decomposed().0;
    assert!(parent.iter().zip([0.3, 0.0, -0.4]).all(|(a, b)| (a - b).abs() < 1e-6), "the node keeps its place");
    let children: Vec<usize> =
        node["children"].as_array().unwrap().iter().map(|c| c.as_u64().unwrap() as usize).collect();
    assert_eq!(children.len(), 3);
    let mut uv_sets = Vec::new();
    for (k, (&child, instance)) in children.iter().zip(&instances).enumerate() {
        let child_json = &out["nodes"][child];
        let child = document.nodes().nth(child).unwrap();
        let (t, r, s) = child.transform().decomposed();
        let close = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-6);
        assert!(close(&t, &instance.translation.to_array()), "instance {k}: translation {t:?}");
        assert!(close(&r, &instance.rotation.to_array()), "instance {k}: rotation {r:?}");
        assert!(close(&s, &instance.scale.to_array()), "instance {k}: scale {s:?}");
        assert_eq!(child_json["extras"]["EXT_mesh_gpu_instancing"]["_ID"], k, "the custom attribute is kept");
        // The child draws the baked instance: it names the KTX2 lightmap, beside the attribute.
        assert_eq!(child_json["extras"]["bake"]["lightmap"], "boxes.lightmap0.ktx2", "instance {k}");
        let primitive = child.mesh().expect("each instance draws a mesh").primitives().next().unwrap();
        let reader = primitive.reader(|b| Some(&buffers[b.index()]));
        let uv: Vec<[f32; 2]> = reader.read_tex_coords(1).expect("lightmap UVs").into_f32().collect();
        uv_sets.push((child.mesh().unwrap().index(), uv));
    }
    for (i, (mesh_i, uv_i)) in uv_sets.iter().enumerate() {
        for (mesh_j, uv_j) in &uv_sets[i + 1..] {
            assert_ne!(mesh_i, mesh_j, "instances share a mesh");
            assert_ne!(uv_i, uv_j, "instances share lightmap UVs");
        }
    }
    let report: bake::report::Report =
        serde_json::from_slice(&std::fs::read(dir.path().join("out/report.json")).unwrap()).unwrap();
    let energy = &report.scenes[0].energy;
    let instances: Vec<Option<usize>> = energy.iter().filter(|e| e.node == 1).map(|e| e.instance).collect();
    assert_eq!(instances, [Some(0), Some(1), Some(2)]);
    assert!(energy.iter().filter(|e| e.node == 1).all(|e| e.stats.texels > 0 && e.name.starts_with("boxes[")));
}

#[test]
fn a_report_longer_than_a_pipe_buffer_reads_back_whole() {
    // 3,000 unused accessors: one message each, a report far past 64 KiB.
    let dir = tempfile::tempdir().unwrap();
    let accessors: Vec<serde_json::Value> =
        (0..3000).map(|_| serde_json::json!({ "componentType": 5126, "count": 1, "type": "SCALAR" })).collect();
    let file = dir.path().join("unused.gltf");
    let document = serde_json::json!({ "asset": { "version": "2.0" }, "accessors": accessors });
    std::fs::write(&file, serde_json::to_vec(&document).unwrap()).unwrap();
    let (errors, _, messages) = validate(&file);
    assert_eq!(errors, 0, "{:?}", &messages[..3]);
    assert!(messages.len() >= 3000, "{} messages", messages.len());
}

#[test]
fn morph_targets_are_kept_and_follow_the_unwrapped_vertices() {
    // A box on the ground whose node draws it with morph weights [0, 0.5]:
    // target 0 moves every vertex, target 1 raises the top and displaces the
    // normals and the input's own TEXCOORD_1 (which the lightmap UVs push to
    // TEXCOORD_2, its displacement with it).
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(6.0, 6.0, 1), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    let data = MeshData::cuboid([0.6, 0.6, 0.6]);
    let cube = scene.mesh("box", &data, None);
    let count = data.positions.len();
    scene.morph_target(cube, "POSITION", &vec![[2.0, 0.0, 0.0]; count]);
    let raise: Vec<[f32; 3]> = data.positions.iter().map(|p| [0.0, if p[1] > 0.0 { 1.0 } else { 0.0 }, 0.0]).collect();
    let target = scene.morph_target(cube, "POSITION", &raise);
    let node = scene.node("box", cube, Placement::at(glam::Vec3::new(0.0, 0.3, 0.0)));
    scene.node_weights(node, &[0.0, 0.5]);
    let glb = scene.to_glb();
    let parsed = gltf::binary::Glb::from_slice(&glb).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&parsed.json).unwrap();
    let primitive = &mut json["meshes"][cube]["primitives"][0];
    let normal = primitive["attributes"]["NORMAL"].clone();
    let uv0 = primitive["attributes"]["TEXCOORD_0"].clone();
    primitive["attributes"]["TEXCOORD_1"] = uv0.clone();
    primitive["targets"][target]["NORMAL"] = normal;
    primitive["targets"][target]["TEXCOORD_1"] = uv0;
    let input = dir.path().join("morph.glb");
    let bin = parsed.bin.unwrap().into_owned();
    std::fs::write(&input, bake::export::glb::encode(&serde_json::to_vec(&json).unwrap(), &bin)).unwrap();
    assert_valid(&input);

    // Every triangle as its morphed corners, rounded, in a rotation-free order.
    let weights = [0.0f32, 0.5];
    let morphed_triangles = |file: &Path| -> (Vec<[[i64; 3]; 3]>, gltf::json::Value) {
        let (document, buffers, _) = gltf::import(file).unwrap();
        let mesh = document.nodes().nth(node).unwrap().mesh().unwrap();
        let primitive = mesh.primitives().next().unwrap();
        let reader = primitive.reader(|b| Some(&buffers[b.index()]));
        let mut positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        let targets: Vec<_> = reader.read_morph_targets().collect();
        assert_eq!(targets.len(), 2, "{}: both targets are kept", file.display());
        for ((target_positions, _, _), w) in targets.into_iter().zip(weights) {
            for (p, d) in positions.iter_mut().zip(target_positions.expect("POSITION displacements")) {
                (0..3).for_each(|c| p[c] += w * d[c]);
            }
        }
        let round = |p: [f32; 3]| p.map(|c| (c * 1e4).round() as i64);
        let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        let mut triangles: Vec<[[i64; 3]; 3]> = indices
            .chunks_exact(3)
            .map(|t| {
                let mut corners = [0, 1, 2].map(|k| round(positions[t[k] as usize]));
                let first = (0..3).min_by_key(|&k| corners[k]).unwrap();
                corners.rotate_left(first);
                corners
            })
            .collect();
        triangles.sort();
        let json = serde_json::from_slice(&gltf::binary::Glb::from_slice(&std::fs::read(file).unwrap()).unwrap().json);
        (triangles, json.unwrap())
    };
    bake(&input, &dir.path().join("out"), &[]);
    let output = dir.path().join("out/morph.glb");
    assert_valid(&output);
    let (before, _) = morphed_triangles(&input);
    let (after, out) = morphed_triangles(&output);
    assert_eq!(after, before, "the output's morphed triangles are the input's");
    assert!(after.iter().flatten().any(|p| p[1] == 8_000), "the top (local y 0.3) raised by half of 1 m");

    let box_primitive = &out["meshes"][out["nodes"][node]["mesh"].as_u64().unwrap() as usize]["primitives"][0];
    let vertices =
        out["accessors"][box_primitive["attributes"]["POSITION"].as_u64().unwrap() as usize]["count"].clone();
    let targets = box_primitive["targets"].as_array().unwrap();
    let names: Vec<Vec<&String>> = targets.iter().map(|t| t.as_object().unwrap().keys().collect()).collect();
    assert_eq!(names, [vec!["POSITION"], vec!["NORMAL", "POSITION", "TEXCOORD_2"]]);
    for accessor in targets.iter().flat_map(|t| t.as_object().unwrap().values()) {
        assert_eq!(out["accessors"][accessor.as_u64().unwrap() as usize]["count"], vertices);
    }
    assert!(box_primitive["attributes"]["TEXCOORD_2"].is_u64(), "the input's TEXCOORD_1 moved");
}

#[test]
fn a_cut_out_keeps_its_alpha_texture_in_the_baked_material() {
    // A fence quad standing on a ground, alpha-masked by a striped texture,
    // with vertex colours; the ground is plain.
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(4.0, 4.0, 1), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    let fence = scene.material("fence", [0.8, 0.7, 0.5, 0.9], [0.0; 3]);
    let stripes =
        image::RgbaImage::from_fn(64, 64, |x, _| image::Rgba([200, 200, 200, if x % 16 < 8 { 255 } else { 0 }]));
    let texture = scene.png_texture(&stripes, 10497);
    scene.base_color_texture(fence, texture, None);
    scene.alpha_mask(fence, 0.4);
    let quad = scene.mesh("fence", &MeshData::plane(2.0, 1.0, 1), Some(fence));
    scene.vertex_colors(quad, &[[1.0, 0.5, 0.5]; 4]);
    let upright = glam::Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    scene.node("fence", quad, Placement::at(glam::Vec3::new(0.0, 0.5, 0.0)).rotated(upright));
    let input = dir.path().join("fence.glb");
    std::fs::write(&input, scene.to_glb()).unwrap();
    let out = dir.path().join("out");
    bake(&input, &out, &[]);
    let baked = out.join("fence.glb");
    assert_valid(&baked);

    let asset = bake::asset::SourceAsset::load(&baked).unwrap();
    let json = &asset.json;
    let material_of =
        |mesh: usize| &json["materials"][json["meshes"][mesh]["primitives"][0]["material"].as_u64().unwrap() as usize];
    // The ground's baked material is unlit, the atlas its base colour.
    let ground = material_of(0);
    assert!(ground["extensions"].get("KHR_materials_unlit").is_some(), "{ground}");
    let atlas = ground["pbrMetallicRoughness"]["baseColorTexture"].clone();
    assert_eq!(atlas["texCoord"], 1);
    // The fence's shows the same atlas as emission over a black base colour
    // that keeps the stripes (and the factor's alpha) for its cut-out.
    let cut_out = material_of(1);
    eprintln!("{cut_out:#}");
    assert_eq!(cut_out["emissiveTexture"], atlas);
    assert_eq!(cut_out["emissiveFactor"], serde_json::json!([1.0, 1.0, 1.0]));
    let base = &cut_out["pbrMetallicRoughness"];
    assert_eq!(base["baseColorFactor"], serde_json::json!([0.0, 0.0, 0.0, 0.8999999761581421]));
    assert_eq!(base["baseColorTexture"], serde_json::json!({ "index": texture }));
    assert_eq!((&cut_out["alphaMode"], &cut_out["alphaCutoff"]), (&"MASK".into(), &0.4f32.into()));
    assert_eq!(cut_out["extensions"]["KHR_materials_specular"]["specularFactor"], 0.0);
    assert!(cut_out["extensions"].get("KHR_materials_unlit").is_none());
    let used = json["extensionsUsed"].as_array().unwrap();
    assert!(used.contains(&"KHR_materials_specular".into()), "{used:?}");
    assert!(json.get("extensionsRequired").is_none());

    // Baking the baked file again reads each primitive's own material (its
    // `pbr+lightmap` variant), not the baked one.
    let again = bake::import::from_asset(asset).unwrap();
    let names: Vec<_> = again.primitives.iter().map(|p| again.materials[p.material.unwrap()].name.clone()).collect();
    assert_eq!(names, [Some("ground".to_string()), Some("fence".to_string())]);
    let fence = &again.materials[again.primitives[1].material.unwrap()];
    assert_eq!(fence.base_color, [0.8, 0.7, 0.5, 0.9]);
    assert!(fence.base_color_texture.is_some());
    // What it is drawn with stays known, with its images decoded, for what shows the file.
    let drawn = &again.materials[again.primitives[1].drawn_material.unwrap()];
    assert_eq!(drawn.name.as_deref(), Some("fence (baked)"));
    let atlas = drawn.emissive_texture.as_ref().expect("the atlas as emission");
    assert!(again.images[atlas.image].is_some(), "the atlas is decoded");
}

#[test]
fn an_unlit_material_keeps_showing_its_own_colour() {
    // A sign whose material is unlit (as a photogrammetry scan's, lighting
    // in its texture) stands on a lit ground: after the bake it still shows
    // its own colour, while the ground shows the baked atlas.
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SceneBuilder::new();
    scene.object("ground", &MeshData::plane(4.0, 4.0, 1), [0.6, 0.6, 0.6, 1.0], [0.0; 3], Placement::default());
    scene.object(
        "sign",
        &MeshData::cuboid([1.0, 0.6, 0.1]),
        [0.9, 0.3, 0.1, 1.0],
        [0.0; 3],
        Placement::at(glam::Vec3::Y * 0.3),
    );
    let glb = scene.to_glb();
    let parsed = gltf::binary::Glb::from_slice(&glb).unwrap();
    let mut json: serde_json::Value = serde_json::from_slice(&parsed.json).unwrap();
    json["materials"][1]["extensions"] = serde_json::json!({ "KHR_materials_unlit": {} });
    json["extensionsUsed"] = serde_json::json!(["KHR_materials_unlit"]);
    let input = dir.path().join("sign.glb");
    let bin = parsed.bin.unwrap().into_owned();
    std::fs::write(&input, bake::export::glb::encode(&serde_json::to_vec(&json).unwrap(), &bin)).unwrap();
    let out = dir.path().join("out");
    bake(&input, &out, &[]);
    let baked = out.join("sign.glb");
    assert_valid(&baked);
    let asset = bake::asset::SourceAsset::load(&baked).unwrap();
    let material_of = |mesh: usize| {
        let index = asset.json["meshes"][mesh]["primitives"][0]["material"].as_u64().unwrap() as usize;
        asset.json["materials"][index].clone()
    };
    let (ground, sign) = (material_of(0), material_of(1));
    assert_eq!(ground["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"], 1, "{ground}");
    assert_eq!(sign["name"], "sign", "{sign}");
    assert!(sign["extensions"].get("KHR_materials_unlit").is_some(), "{sign}");
    assert_eq!(
        sign["pbrMetallicRoughness"]["baseColorFactor"],
        json["materials"][1]["pbrMetallicRoughness"]["baseColorFactor"]
    );
    assert!(sign["pbrMetallicRoughness"].get("baseColorTexture").is_none(), "no atlas on it: {sign}");
    // Nor a lightmap, which three.js would shade it with; the ground's keeps the extension in use.
    assert!(sign["extensions"].get("MOZ_lightmap").is_none(), "{sign}");
    let ground_variants = &asset.json["meshes"][0]["primitives"][0]["extensions"]["KHR_materials_variants"];
    let ground_pbr = &asset.json["materials"][ground_variants["mappings"][1]["material"].as_u64().unwrap() as usize];
    assert!(ground_pbr.pointer("/extensions/MOZ_lightmap").is_some(), "{ground_pbr}");
    assert!(asset.json["extensionsUsed"].as_array().unwrap().contains(&"MOZ_lightmap".into()));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let notices = report["scenes"][0]["notices"].to_string();
    assert!(notices.contains("material 1 'sign' is unlit (KHR_materials_unlit): its primitives keep it"), "{notices}");
}

#[test]
fn a_glass_pane_keeps_its_own_material_and_takes_no_lightmap() {
    let mut builder = SceneBuilder::new();
    builder.object("ground", &MeshData::plane(4.0, 4.0, 4), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let glass = builder.material("window glass", [0.9, 0.95, 1.0, 1.0], [0.0; 3]);
    builder.transmission(glass, 1.0);
    let mesh = builder.mesh("pane", &MeshData::cuboid([1.0, 0.02, 1.0]), Some(glass));
    builder.node("pane", mesh, Placement::at(glam::Vec3::Y * 0.3));
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("window.glb");
    std::fs::write(&input, builder.to_glb()).unwrap();
    let out = dir.path().join("out");
    bake(&input, &out, &[]);
    assert_valid(&out.join("window.glb"));

    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let notices = report["scenes"][0]["notices"].to_string();
    let expected = "material 1 'window glass' transmits light (KHR_materials_transmission, factor 1): its primitives \
                    are left out of the bake";
    assert!(notices.contains(expected), "no notice says '{expected}': {notices}");
    let glb = std::fs::read(out.join("window.glb")).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&gltf::binary::Glb::from_slice(&glb).unwrap().json).unwrap();
    let pane = &json["meshes"][1]["primitives"][0];
    assert_eq!(pane["material"], serde_json::json!(glass), "the pane keeps its material: {pane}");
    assert!(pane.pointer("/attributes/TEXCOORD_1").is_none() && pane.get("extensions").is_none(), "{pane}");
    assert_eq!(
        json["materials"][glass]["extensions"]["KHR_materials_transmission"]["transmissionFactor"],
        serde_json::json!(1.0)
    );
    assert!(json["extensionsUsed"].as_array().unwrap().contains(&serde_json::json!("KHR_materials_transmission")));
    // The ground is baked as usual.
    assert!(json["meshes"][0]["primitives"][0].pointer("/attributes/TEXCOORD_1").is_some());
}
