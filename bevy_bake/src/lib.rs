//! Bevy plugin for glTF files baked by `bake`: when Bevy loads one, every baked primitive gets its
//! [`Lightmap`] (the `NAME.lightmap0.ktx2` its node's `extras.bake` names, on `TEXCOORD_1`) and the PBR
//! material of the `pbr+lightmap` variant (`KHR_materials_variants`, which Bevy's glTF loader ignores), and
//! each scene baked with `--probes` gets its [`IrradianceVolume`] (`extras.bake.probes`).
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_bake::BakePlugin;
//!
//! App::new()
//!     .add_plugins((DefaultPlugins, BakePlugin)) // after DefaultPlugins: it hooks into the glTF loader
//!     .add_systems(Startup, |mut commands: Commands, assets: Res<AssetServer>| {
//!         commands.spawn(WorldAssetRoot(assets.load("level.glb#Scene0")));
//!     })
//!     .run();
//! ```
//!
//! The work is done while the glTF loads, through the loader's extension hooks
//! ([`GltfExtensionHandler`]): the components are part of the loaded scene asset, so every spawn of it has
//! them, and the KTX2 files are dependencies of the scene (loaded with it). Units: the lightmap and the
//! probes hold L_lm = E/π, which Bevy shades as albedo · L_lm with `lightmap_exposure` 1; the camera
//! exposure that shows them as bake's unlit preview does is each primitive's [`BakedPrimitive::ev100`].

use std::collections::HashMap;

use bevy::asset::LoadContext;
use bevy::ecs::world::EntityWorldMut;
use bevy::gltf::extensions::{ErasedGltfExtensionHandler, GltfExtensionHandler, GltfExtensionHandlers};
use bevy::gltf::{GltfAssetLabel, GltfExtras, gltf};
use bevy::light::{IrradianceVolume, LightProbe};
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use serde_json::Value;

/// The variant whose material is the input's own PBR material (bake's `pbr+lightmap`).
pub const PBR_VARIANT: &str = "pbr+lightmap";

/// Adds bake's glTF extension handler to Bevy's glTF loader. Add it after `DefaultPlugins` (or whatever
/// adds `GltfPlugin` and `PbrPlugin`).
pub struct BakePlugin;

impl Plugin for BakePlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<BakedPrimitive>().register_type::<BakedProbes>();
        let handlers = app
            .world()
            .get_resource::<GltfExtensionHandlers>()
            .expect("BakePlugin needs Bevy's GltfPlugin: add it after DefaultPlugins");
        handlers.0.write_blocking().push(Box::new(BakeGltfHandler::default()));
    }
}

/// On each primitive entity the plugin gave a [`Lightmap`]: the camera EV100 at which Bevy, with no tone
/// mapping, shows albedo · L_lm as bake's unlit preview does (`-(--exposure) - log2 1.2`).
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Component, Default, Clone)]
pub struct BakedPrimitive {
    pub ev100: f32,
}

/// On the [`IrradianceVolume`] entity the plugin spawned under a scene baked with `--probes`.
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Component, Default, Clone)]
pub struct BakedProbes {
    /// Probes along x, y, z.
    pub counts: UVec3,
}

/// A node's `extras.bake` record: its lightmap and which primitives of its mesh draw with it.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeBake {
    /// The KTX2 lightmap, relative to the glTF file.
    pub lightmap: String,
    /// The UV set the lightmap is read through (Bevy's `Lightmap` reads `ATTRIBUTE_UV_1`: 1).
    pub tex_coord: u32,
    /// min x, min y, max x, max y in the lightmap.
    pub uv_rect: [f32; 4],
    /// Indices of the node's mesh primitives that are baked.
    pub primitives: Vec<usize>,
    pub ev100: f32,
}

/// A scene's `extras.bake.probes` record: Bevy's irradiance volume and where it stands.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneProbes {
    /// The KTX2 voxels, relative to the glTF file.
    pub ktx2: String,
    pub counts: [u32; 3],
    /// The volume's `Transform` (Bevy's volume is a unit cube centred on its origin).
    pub translation: [f32; 3],
    pub scale: [f32; 3],
}

/// The `bake` object of an extras string: `None` when the extras are not an object with one.
fn bake_object(extras: &str) -> Result<Option<Value>, String> {
    let value: Value = serde_json::from_str(extras).map_err(|e| format!("extras are not JSON: {e}"))?;
    Ok(value.get("bake").cloned())
}

fn string(object: &Value, key: &str) -> Result<String, String> {
    object.get(key).and_then(Value::as_str).map(str::to_owned).ok_or_else(|| format!("no string `{key}`"))
}

fn number(value: &Value, what: &str) -> Result<f32, String> {
    match value.as_f64() {
        Some(x) if x.is_finite() => Ok(x as f32),
        _ => Err(format!("`{what}` is not a finite number: {value}")),
    }
}

fn numbers<const N: usize>(object: &Value, key: &str) -> Result<[f32; N], String> {
    let list = object.get(key).and_then(Value::as_array).ok_or_else(|| format!("no array `{key}`"))?;
    if list.len() != N {
        return Err(format!("`{key}` has {} numbers, not {N}", list.len()));
    }
    let mut out = [0.0; N];
    for (o, v) in out.iter_mut().zip(list) {
        *o = number(v, key)?;
    }
    Ok(out)
}

fn index(value: &Value, what: &str) -> Result<usize, String> {
    value.as_u64().map(|i| i as usize).ok_or_else(|| format!("`{what}` holds {value}, not an index"))
}

impl NodeBake {
    /// Reads a node's extras (the JSON string Bevy keeps in [`GltfExtras`]). `Ok(None)`: no `bake.lightmap`,
    /// so not a baked node; `Err`: a record that names a lightmap but cannot be used.
    pub fn from_extras(extras: &str) -> Result<Option<NodeBake>, String> {
        let Some(bake) = bake_object(extras)? else { return Ok(None) };
        if bake.get("lightmap").is_none() {
            return Ok(None);
        }
        let lightmap = string(&bake, "lightmap")?;
        let tex_coord = match bake.get("texCoord") {
            None => 1,
            Some(v) => u32::try_from(index(v, "texCoord")?).map_err(|_| format!("texCoord {v}"))?,
        };
        let uv_rect = numbers::<4>(&bake, "uv_rect")?;
        let primitives = bake
            .get("primitives")
            .and_then(Value::as_array)
            .ok_or("no array `primitives`")?
            .iter()
            .map(|v| index(v, "primitives"))
            .collect::<Result<Vec<_>, _>>()?;
        let ev100 = number(bake.get("ev100").ok_or("no `ev100`")?, "ev100")?;
        Ok(Some(NodeBake { lightmap, tex_coord, uv_rect, primitives, ev100 }))
    }

    pub fn rect(&self) -> Rect {
        let [x0, y0, x1, y1] = self.uv_rect;
        Rect::new(x0, y0, x1, y1)
    }
}

impl SceneProbes {
    /// Reads a scene's extras. `Ok(None)`: no `bake.probes` (baked without `--probes`, or not baked).
    pub fn from_extras(extras: &str) -> Result<Option<SceneProbes>, String> {
        let Some(bake) = bake_object(extras)? else { return Ok(None) };
        let Some(probes) = bake.get("probes") else { return Ok(None) };
        let ktx2 = string(probes, "ktx2")?;
        let counts = numbers::<3>(probes, "counts")?;
        if counts.iter().any(|&c| c < 1.0 || c.fract() != 0.0) {
            return Err(format!("probe counts {counts:?} are not positive integers"));
        }
        let translation = numbers::<3>(probes, "translation")?;
        let scale = numbers::<3>(probes, "scale")?;
        if scale.iter().any(|&s| s <= 0.0) {
            return Err(format!("probe volume scale {scale:?} is not positive"));
        }
        Ok(Some(SceneProbes { ktx2, counts: counts.map(|c| c as u32), translation, scale }))
    }

    pub fn transform(&self) -> Transform {
        Transform::from_translation(Vec3::from(self.translation)).with_scale(Vec3::from(self.scale))
    }
}

/// For the glTF document `doc` (its JSON), the material that variant `variant` maps each primitive to:
/// (mesh index, primitive index) → material index, for the primitives whose `KHR_materials_variants`
/// mappings name that variant. Empty when the document has no such variant.
pub fn variant_materials(doc: &Value, variant: &str) -> Result<HashMap<(usize, usize), usize>, String> {
    let mut out = HashMap::new();
    let Some(variants) = doc.pointer("/extensions/KHR_materials_variants/variants") else { return Ok(out) };
    let variants = variants.as_array().ok_or("KHR_materials_variants.variants is not an array")?;
    let Some(wanted) = variants.iter().position(|v| v.get("name").and_then(Value::as_str) == Some(variant)) else {
        return Ok(out);
    };
    let meshes = doc.get("meshes").and_then(Value::as_array).map(Vec::as_slice).unwrap_or_default();
    for (m, mesh) in meshes.iter().enumerate() {
        let primitives = mesh.get("primitives").and_then(Value::as_array).map(Vec::as_slice).unwrap_or_default();
        for (p, primitive) in primitives.iter().enumerate() {
            let Some(mappings) = primitive.pointer("/extensions/KHR_materials_variants/mappings") else {
                continue;
            };
            let mappings = mappings.as_array().ok_or_else(|| format!("mesh {m} primitive {p}: mappings"))?;
            for mapping in mappings {
                let listed = mapping.get("variants").and_then(Value::as_array).into_iter().flatten();
                if listed.filter_map(Value::as_u64).any(|v| v as usize == wanted) {
                    let material =
                        mapping.get("material").ok_or_else(|| format!("mesh {m} primitive {p}: no material"))?;
                    out.insert((m, p), index(material, "material")?);
                    break;
                }
            }
        }
    }
    Ok(out)
}

/// [`variant_materials`] of [`PBR_VARIANT`] for a document as Bevy's loader parsed it (`.gltf` or `.glb`):
/// the gltf crate keeps extensions it does not know, such as `KHR_materials_variants`, as JSON.
fn pbr_materials(gltf: &gltf::Gltf) -> Result<HashMap<(usize, usize), usize>, String> {
    let doc = serde_json::to_value(gltf.document.as_json()).map_err(|e| e.to_string())?;
    variant_materials(&doc, PBR_VARIANT)
}

/// A primitive entity the loader spawned into the scene being loaded.
#[derive(Clone, Copy, Debug)]
struct Spawned {
    entity: Entity,
    mesh: usize,
    primitive: usize,
    scale_inverted: bool,
}

/// Cloned by the loader for each glTF it loads.
#[derive(Clone, Default)]
struct BakeGltfHandler {
    /// (mesh, primitive) → the `pbr+lightmap` material.
    pbr_materials: HashMap<(usize, usize), usize>,
    /// The current scene's primitive entities, handled once the scene is complete (after every other
    /// handler, Bevy's PBR one that inserts the default material included, has seen them).
    spawned: Vec<Spawned>,
}

fn path_in(load_context: &LoadContext, uri: &str) -> Option<bevy::asset::AssetPath<'static>> {
    match load_context.path().resolve_embed_str(uri) {
        Ok(path) => Some(path),
        Err(e) => {
            warn!("{}: bake: cannot resolve {uri:?}: {e}", load_context.path());
            None
        }
    }
}

impl GltfExtensionHandler for BakeGltfHandler {
    fn dyn_clone(&self) -> Box<dyn ErasedGltfExtensionHandler> {
        Box::new(self.clone())
    }

    fn on_root(&mut self, load_context: &mut LoadContext<'_>, gltf: &gltf::Gltf, _: &bevy::gltf::GltfLoaderSettings) {
        self.spawned.clear();
        self.pbr_materials = pbr_materials(gltf).unwrap_or_else(|e| {
            warn!("{}: bake: KHR_materials_variants: {e}", load_context.path());
            HashMap::new()
        });
    }

    fn on_spawn_mesh_and_material(
        &mut self,
        _: &mut LoadContext<'_>,
        primitive: &gltf::Primitive,
        mesh: &gltf::Mesh,
        _: &gltf::Material,
        entity: &mut EntityWorldMut,
        material_label: &str,
    ) {
        self.spawned.push(Spawned {
            entity: entity.id(),
            mesh: mesh.index(),
            primitive: primitive.index(),
            scale_inverted: material_label.ends_with(" (inverted)"),
        });
    }

    fn on_scene_completed(
        &mut self,
        load_context: &mut LoadContext<'_>,
        scene: &gltf::Scene,
        world_root_id: Entity,
        world: &mut World,
    ) {
        for spawned in std::mem::take(&mut self.spawned) {
            // The loader spawns a node's primitives as children of the node's entity, which has its extras.
            let Some(node) = world.get::<ChildOf>(spawned.entity).map(ChildOf::parent) else { continue };
            let Some(extras) = world.get::<GltfExtras>(node) else { continue };
            let bake = match NodeBake::from_extras(&extras.value) {
                Ok(Some(bake)) => bake,
                Ok(None) => continue,
                Err(e) => {
                    warn!("{}: bake: mesh {} extras.bake: {e}", load_context.path(), spawned.mesh);
                    continue;
                }
            };
            if !bake.primitives.contains(&spawned.primitive) {
                continue;
            }
            if bake.tex_coord != 1 {
                warn!(
                    "{}: bake: lightmap on TEXCOORD_{}: Bevy reads lightmaps through UV 1 only",
                    load_context.path(),
                    bake.tex_coord
                );
                continue;
            }
            let Some(path) = path_in(load_context, &bake.lightmap) else { continue };
            let image = load_context.load::<Image>(path);
            let material = self.pbr_materials.get(&(spawned.mesh, spawned.primitive)).map(|&index| {
                let mut label = GltfAssetLabel::Material { index, is_scale_inverted: spawned.scale_inverted };
                if spawned.scale_inverted && !load_context.has_labeled_asset(label.to_string()) {
                    // The loader makes a material's "inverted" form only where a node uses it so; the PBR
                    // material of a mirrored node may have none. Its faces then cull the wrong way round.
                    warn!("{}: bake: no inverted form of material {index} for a mirrored node", load_context.path());
                    label = GltfAssetLabel::Material { index, is_scale_inverted: false };
                }
                load_context.get_label_handle::<StandardMaterial>(format!("{label}/std"))
            });
            let mut entity = world.entity_mut(spawned.entity);
            entity.insert((
                Lightmap { image, uv_rect: bake.rect(), bicubic_sampling: false },
                BakedPrimitive { ev100: bake.ev100 },
            ));
            if let Some(material) = material {
                entity.insert(MeshMaterial3d(material));
            }
        }

        let probes = match scene.extras().as_ref().map(|extras| SceneProbes::from_extras(extras.get())) {
            Some(Ok(Some(probes))) => probes,
            None | Some(Ok(None)) => return,
            Some(Err(e)) => {
                warn!("{}: bake: scene {} extras.bake.probes: {e}", load_context.path(), scene.index());
                return;
            }
        };
        let Some(path) = path_in(load_context, &probes.ktx2) else { return };
        let voxels = load_context.load::<Image>(path);
        world.spawn((
            Name::new("bake probes"),
            // The lightmaps hold this light already: the volume is for what has none.
            IrradianceVolume { voxels, intensity: 1.0, affects_lightmapped_meshes: false },
            LightProbe::default(),
            probes.transform(),
            BakedProbes { counts: UVec3::from_array(probes.counts) },
            ChildOf(world_root_id),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    const NODE: &str = r#"{"bake": {"content": "L_lm = E/pi", "ev100": -0.2630344058337938,
        "lightmap": "sphere_on_ground.lightmap0.ktx2", "primitives": [0, 2], "texCoord": 1,
        "uv_rect": [0.0, 0.25, 1.0, 0.75]}, "user": 3}"#;

    #[test]
    fn node_record_is_read() {
        let bake = NodeBake::from_extras(NODE).unwrap().unwrap();
        assert_eq!(bake.lightmap, "sphere_on_ground.lightmap0.ktx2");
        assert_eq!(bake.tex_coord, 1);
        assert_eq!(bake.primitives, vec![0, 2]);
        assert_eq!(bake.uv_rect, [0.0, 0.25, 1.0, 0.75]);
        assert_eq!(bake.rect(), Rect::new(0.0, 0.25, 1.0, 0.75));
        assert!((bake.ev100 + 0.263).abs() < 1e-3);
    }

    #[test]
    fn nodes_without_a_lightmap_are_not_baked() {
        assert_eq!(NodeBake::from_extras(r#"{"user": 1}"#), Ok(None));
        assert_eq!(NodeBake::from_extras(r#"[1, 2]"#), Ok(None));
        // A scene's record (probes only) on a node is not a node's record.
        assert_eq!(NodeBake::from_extras(r#"{"bake": {"probes": {}}}"#), Ok(None));
    }

    #[test]
    fn broken_node_records_are_errors() {
        let broken = |f: &dyn Fn(&mut Value)| {
            let mut v: Value = serde_json::from_str(NODE).unwrap();
            f(&mut v["bake"]);
            NodeBake::from_extras(&v.to_string())
        };
        assert!(broken(&|b| b["uv_rect"] = json!([0, 0, 1])).is_err());
        assert!(broken(&|b| b["primitives"] = json!([-1])).is_err());
        assert!(broken(&|b| b["lightmap"] = json!(7)).is_err());
        assert!(broken(&|b| b["ev100"] = json!("x")).is_err());
        assert!(NodeBake::from_extras("{").is_err());
        // texCoord defaults to 1 and is read when given.
        assert_eq!(broken(&|b| b["texCoord"] = json!(2)).unwrap().unwrap().tex_coord, 2);
        assert_eq!(broken(&|b| drop(b.as_object_mut().unwrap().remove("texCoord"))).unwrap().unwrap().tex_coord, 1);
    }

    #[test]
    fn scene_probes_are_read() {
        let extras = r#"{"bake": {"probes": {"content": "...", "counts": [20, 5, 20],
            "data": "s.probes.bin", "json": "s.probes.json", "ktx2": "s.probes.ktx2",
            "scale": [10.0, 2.5, 10.0], "translation": [0.0, 1.25, -3.0]}}}"#;
        let probes = SceneProbes::from_extras(extras).unwrap().unwrap();
        assert_eq!(probes.ktx2, "s.probes.ktx2");
        assert_eq!(probes.counts, [20, 5, 20]);
        let t = probes.transform();
        assert_eq!(t.translation, Vec3::new(0.0, 1.25, -3.0));
        assert_eq!(t.scale, Vec3::new(10.0, 2.5, 10.0));
        assert_eq!(t.rotation, Quat::IDENTITY);
        assert_eq!(SceneProbes::from_extras(r#"{"bake": {}}"#), Ok(None));
        assert_eq!(SceneProbes::from_extras(r#"{}"#), Ok(None));
        assert!(
            SceneProbes::from_extras(
                r#"{"bake": {"probes": {"ktx2": "a", "counts": [2, 0, 1],
            "scale": [1, 1, 1], "translation": [0, 0, 0]}}}"#
            )
            .is_err()
        );
    }

    /// What bake writes: each baked primitive's `material` is the unlit preview, variant 1 of 2 maps it to
    /// the PBR material; the input's own variants come first.
    fn baked_doc() -> Value {
        json!({
            "extensions": {"KHR_materials_variants": {"variants": [{"name": "red"}, {"name": "baked"}, {"name": "pbr+lightmap"}]}},
            "meshes": [
                {"primitives": [
                    {"material": 2, "extensions": {"KHR_materials_variants": {"mappings": [
                        {"material": 2, "variants": [1]}, {"material": 0, "variants": [2]}]}}},
                    {"material": 5}
                ]},
                {"primitives": [
                    {"material": 3, "extensions": {"KHR_materials_variants": {"mappings": [
                        {"material": 4, "variants": [0]}, {"material": 3, "variants": [1]},
                        {"material": 1, "variants": [2, 0]}]}}}
                ]}
            ]
        })
    }

    #[test]
    fn pbr_variant_materials_come_from_the_mappings() {
        let map = variant_materials(&baked_doc(), PBR_VARIANT).unwrap();
        assert_eq!(map, HashMap::from([((0, 0), 0), ((1, 0), 1)]));
        let baked = variant_materials(&baked_doc(), "baked").unwrap();
        assert_eq!(baked, HashMap::from([((0, 0), 2), ((1, 0), 3)]));
    }

    /// The mappings survive Bevy's parse (the gltf crate): the handler reads them from there.
    #[test]
    fn mappings_survive_the_gltf_crate() {
        let mut doc = baked_doc();
        doc["asset"] = json!({"version": "2.0"});
        doc["extensionsUsed"] = json!(["KHR_materials_variants"]);
        doc["accessors"] =
            json!([{"componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}]);
        doc["materials"] = json!([{}, {}, {}, {}, {}, {}]);
        for mesh in doc["meshes"].as_array_mut().unwrap() {
            for primitive in mesh["primitives"].as_array_mut().unwrap() {
                primitive["attributes"] = json!({"POSITION": 0});
            }
        }
        let gltf = gltf::Gltf::from_slice_without_validation(doc.to_string().as_bytes()).unwrap();
        assert_eq!(pbr_materials(&gltf).unwrap(), HashMap::from([((0, 0), 0), ((1, 0), 1)]));
    }

    #[test]
    fn no_variant_no_materials() {
        let mut doc = baked_doc();
        doc["extensions"] = json!({});
        assert!(variant_materials(&doc, PBR_VARIANT).unwrap().is_empty());
        assert!(variant_materials(&baked_doc(), "blue").unwrap().is_empty());
        let mut bad = baked_doc();
        bad["meshes"][0]["primitives"][0]["extensions"]["KHR_materials_variants"]["mappings"][1]["material"] =
            json!("x");
        assert!(variant_materials(&bad, PBR_VARIANT).is_err());
    }
}
