//! The probe volume's files (README, "Light probes"):
//!
//! - `NAME.probes.ktx2`: Bevy's `IrradianceVolume` texture. For a grid of
//!   (Rx, Ry, Rz) probes, a 3D texture of (Rx, 2·Ry, 3·Rz) E5B9G9R9 texels:
//!   the face along axis a (0 x, 1 y, 2 z) of probe (x, y, z) at
//!   (x, y + Ry if the face looks down its axis, z + a·Rz), which is where
//!   Bevy's shader (`irradiance_volume.wgsl`) reads it for a normal with
//!   that axis's sign. Bevy places it with a Transform scaling its unit
//!   cube to the probe box (the JSON gives it).
//! - `NAME.probes.json` + `NAME.probes.bin`: the same for any engine, in
//!   full f32: the JSON says where the probes are and how the binary is
//!   laid out.

use anyhow::Result;
use serde_json::{Value, json};

use super::{FACES, Probes};
use crate::export::ktx2;

/// The three files' names for scene `name`.
pub fn file_names(name: &str) -> [String; 3] {
    ["ktx2", "json", "bin"].map(|ext| format!("{name}.probes.{ext}"))
}

/// The volume as Bevy's `IrradianceVolume` texture.
pub fn encode_ktx2(probes: &Probes) -> Result<Vec<u8>> {
    let [nx, ny, nz] = probes.grid.counts.map(|c| c as usize);
    let (width, height) = (nx, 2 * ny);
    let mut texels = vec![[0.0f32; 3]; width * height * 3 * nz];
    for (i, faces) in probes.faces.iter().enumerate() {
        let [x, y, z] = probes.grid.cell(i).map(|c| c as usize);
        for (f, value) in faces.iter().enumerate() {
            let (axis, negative) = (f / 2, f % 2 == 1);
            let t = y + if negative { ny } else { 0 };
            let p = z + axis * nz;
            texels[x + width * (t + height * p)] = *value;
        }
    }
    ktx2::encode_volume(width as u32, height as u32, (3 * nz) as u32, &texels)
}

/// Every probe's faces as little-endian f32: per probe (x fastest), per
/// face in [`FACES`] order, r g b.
pub fn encode_bin(probes: &Probes) -> Vec<u8> {
    probes.faces.iter().flatten().flatten().flat_map(|v| v.to_le_bytes()).collect()
}

/// What each scene of the baked glTF says of the probes
/// (`extras.bake.probes`): the files, and the Transform of Bevy's unit-cube volume.
pub fn gltf_record(name: &str, probes: &Probes) -> Value {
    let [ktx2_name, json_name, bin_name] = file_names(name);
    let (translation, scale) = probes.grid.centre_and_size();
    json!({
        "ktx2": ktx2_name,
        "json": json_name,
        "data": bin_name,
        "counts": probes.grid.counts,
        "translation": translation,
        "scale": scale,
        "content": "ambient cubes (+X -X +Y -Y +Z -Z), irradiance over pi like the lightmap: Bevy's IrradianceVolume \
                    with intensity 1 on an entity with this translation and scale",
    })
}

/// The JSON header: the grid, the units, the layout of the binary, the
/// buried probes and the Transform Bevy needs.
pub fn encode_json(name: &str, probes: &Probes) -> Result<Vec<u8>> {
    let grid = &probes.grid;
    let [ktx2_name, _, bin_name] = file_names(name);
    let (translation, scale) = grid.centre_and_size();
    let buried: Vec<usize> = (0..grid.len()).filter(|&i| probes.buried[i]).collect();
    let header: Value = json!({
        "format": "bake irradiance volume",
        "version": 1,
        "counts": grid.counts,
        "min": grid.min,
        "max": grid.max,
        "spacing": grid.spacing(),
        "position": "probe (x, y, z) stands at min + (max - min) * ((x, y, z) + 0.5) / counts, world metres (glTF axes, +Y up)",
        "faces": FACES,
        "value": "per face: the irradiance E a surface facing along that axis receives at the probe, over pi (the lightmap's \
                  L_lm = E/pi), linear RGB, Rec. 709 primaries; blend the faces by the squared normal components (ambient cube)",
        "data": bin_name,
        "layout": "little-endian f32, probes with x fastest, then y, then z; per probe the faces in 'faces' order; per face r, g, b",
        "buried": buried,
        "buried_meaning": "probes inside geometry (their rays met the backs of surfaces): they hold the mean of their neighbours, not what they saw",
        "bevy": {
            "ktx2": ktx2_name,
            "component": "IrradianceVolume { voxels: the KTX2, intensity: 1.0 }: the same units as the KTX2 lightmap",
            "translation": translation,
            "scale": scale,
        },
    });
    Ok(serde_json::to_vec_pretty(&header)?)
}
