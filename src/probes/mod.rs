//! Light probes (`--probes SPACING`): an irradiance volume for what moves
//! through a baked scene. Over a box (the scene's bounds, or `--probe-box`)
//! stands a grid of probes (`grid`); each holds an ambient cube (Half-Life
//! 2's, as Bevy's `IrradianceVolume` stores it): for each of +X, −X, +Y,
//! −Y, +Z, −Z, the irradiance a surface facing that way would receive there,
//! over π, which is the lightmap's unit L_lm. The light comes from the
//! environment's lights and the scene's punctual lights, each with its
//! shadow ray, and from the solved surfaces along gather rays (`gather`, on
//! the GPU): the solution is read, not solved again.
//!
//! A probe inside geometry sees the backs of surfaces; it is flagged
//! buried and takes its unburied neighbours' light, so an engine blending
//! between probes never pulls in the black inside a wall.

pub mod gather;
pub mod grid;
pub mod write;

use std::time::Instant;

use anyhow::{Result, bail};
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::environment::LightSet;
use crate::gpu::Gpu;
use crate::scene::Scene;
use crate::trace::Surfaces;
pub use gather::Solved;
pub use grid::Grid;

/// The faces of an ambient cube, in the order every output keeps them.
pub const FACES: [&str; 6] = ["+X", "-X", "+Y", "-Y", "+Z", "-Z"];
/// Gather rays per probe unless asked otherwise.
pub const DEFAULT_RAYS: u32 = 1024;
/// A probe whose gather rays meet the back of a surface more often than
/// this is inside geometry (one in open space or a room meets none; one
/// just under a floor meets it with half of them).
const BURIED_BACK_HITS: f64 = 0.25;

/// `--probes`, `--probe-box`, `--probe-rays`.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeOptions {
    /// Largest distance between neighbouring probes, metres.
    pub spacing: f64,
    /// The box to fill (world coordinates, min and max); the scene's bounds when `None`.
    pub region: Option<[[f64; 3]; 2]>,
    /// Gather rays per probe.
    pub rays: u32,
}

/// The baked volume.
pub struct Probes {
    pub grid: Grid,
    /// Per probe (x fastest, then y, then z), the faces in [`FACES`] order:
    /// irradiance over π, linear RGB.
    pub faces: Vec<[[f32; 3]; 6]>,
    /// Per probe: inside geometry, its faces taken from its neighbours.
    pub buried: Vec<bool>,
    pub stats: ProbeStats,
}

/// What the probe stage did, for the report.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProbeStats {
    pub grid: Grid,
    /// Distance between neighbouring probes along x, y and z, metres.
    pub spacing: [f64; 3],
    pub probes: usize,
    /// Gather rays per probe.
    pub rays: u32,
    /// Environment lights and punctual lights, one shadow ray each per probe.
    pub lights: usize,
    pub punctual_lights: usize,
    /// Probes inside geometry (their light taken from their neighbours).
    pub buried: usize,
    /// Ray walks stopped at their longest (counted as blocked).
    pub cut_walks: u64,
    pub seconds: f64,
}

/// Bakes the probes of `grid` (`grid_for`'s) in `solved` under `lights`.
pub fn run(
    gpu: &Gpu,
    solved: &Solved,
    lights: Option<&LightSet>,
    grid: Grid,
    options: &ProbeOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Probes> {
    let start = Instant::now();
    let scene = solved.scene;
    let origin = DVec3::from(scene.origin);
    let positions: Vec<DVec3> = (0..grid.len()).map(|i| grid.position(i) - origin).collect();
    let environment = lights.map_or(&[][..], |l| l.lights.as_slice());
    let pass = gather::GatherPass::new(gpu, scene)?;
    let (gathered, counts) = pass.run(gpu, solved, environment, &positions, options.rays, progress)?;
    let punctual = punctual_light(scene, &positions);
    let mut faces: Vec<[[f32; 3]; 6]> = gathered
        .iter()
        .enumerate()
        .map(|(i, g)| {
            let extra = punctual.as_ref().map_or([DVec3::ZERO; 6], |p| p[i]);
            [0, 1, 2, 3, 4, 5].map(|f| ((g.faces[f] + extra[f]) / std::f64::consts::PI).as_vec3().to_array())
        })
        .collect();
    let rays = f64::from(options.rays.max(1));
    let buried: Vec<bool> = gathered.iter().map(|g| f64::from(g.back_hits) / rays > BURIED_BACK_HITS).collect();
    fill_buried(&grid, &mut faces, &buried);
    let stats = ProbeStats {
        spacing: grid.spacing(),
        probes: grid.len(),
        rays: options.rays,
        lights: environment.len(),
        punctual_lights: scene.lights.len(),
        buried: buried.iter().filter(|&&b| b).count(),
        cut_walks: counts.cut_walks,
        seconds: start.elapsed().as_secs_f64(),
        grid: grid.clone(),
    };
    Ok(Probes { grid, faces, buried, stats })
}

/// The grid over `--probe-box`, or over the scene's bounds; known before
/// the solve, so a spacing that makes too many probes fails at once.
pub fn grid_for(scene: &Scene, options: &ProbeOptions) -> Result<Grid> {
    let (min, max) = match options.region {
        Some([min, max]) => (DVec3::from(min), DVec3::from(max)),
        None => {
            let Some((lo, hi)) = scene.bounds() else { bail!("the scene has no geometry to place probes around") };
            let origin = DVec3::from(scene.origin);
            (lo.as_dvec3() + origin, hi.as_dvec3() + origin)
        }
    };
    Grid::over(min, max, options.spacing)
}

/// Adds light arriving from direction `d` (unit, towards its source) with
/// irradiance `e` at normal incidence to the faces it reaches, each by its
/// cosine.
fn add_to_faces(faces: &mut [DVec3; 6], d: DVec3, e: DVec3) {
    for axis in 0..3 {
        faces[2 * axis] += e * d[axis].max(0.0);
        faces[2 * axis + 1] += e * (-d[axis]).max(0.0);
    }
}

/// The punctual lights' irradiance on each face of each probe, one exact
/// shadow ray per light on the CPU (as the lightmap's punctual pass);
/// `None` for a scene without them.
fn punctual_light(scene: &Scene, positions: &[DVec3]) -> Option<Vec<[DVec3; 6]>> {
    if scene.lights.is_empty() {
        return None;
    }
    let surfaces = Surfaces::new(scene);
    let at = |p: DVec3| {
        let mut faces = [DVec3::ZERO; 6];
        for light in &scene.lights {
            let Some(incident) = light.towards(p) else { continue };
            if !surfaces.blocked(p, incident.direction, incident.distance) {
                add_to_faces(&mut faces, incident.direction, incident.irradiance);
            }
        }
        faces
    };
    Some(positions.par_iter().map(|&p| at(p)).collect())
}

/// Gives each buried probe the mean of its unburied neighbours (six
/// around it), ring by ring outwards from the probes that see the scene.
/// Where no probe does, the probes keep what they gathered.
fn fill_buried(grid: &Grid, faces: &mut [[[f32; 3]; 6]], buried: &[bool]) {
    let mut known: Vec<bool> = buried.iter().map(|b| !b).collect();
    loop {
        let mut updates = Vec::new();
        for i in (0..grid.len()).filter(|&i| !known[i]) {
            let neighbours: Vec<usize> = neighbours(grid, i).filter(|&j| known[j]).collect();
            if neighbours.is_empty() {
                continue;
            }
            let mut mean = [[0.0f32; 3]; 6];
            for j in &neighbours {
                for (m, v) in mean.iter_mut().flatten().zip(faces[*j].iter().flatten()) {
                    *m += v / neighbours.len() as f32;
                }
            }
            updates.push((i, mean));
        }
        if updates.is_empty() {
            return;
        }
        for (i, mean) in updates {
            faces[i] = mean;
            known[i] = true;
        }
    }
}

/// The probes next to probe `i` along each axis.
fn neighbours(grid: &Grid, i: usize) -> impl Iterator<Item = usize> + '_ {
    let cell = grid.cell(i);
    (0..3).flat_map(move |axis| {
        [-1i64, 1].into_iter().filter_map(move |step| {
            let c = i64::from(cell[axis]) + step;
            (c >= 0 && c < i64::from(grid.counts[axis])).then(|| {
                let mut next = cell;
                next[axis] = c as u32;
                grid.index(next)
            })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_buried_probe_takes_its_open_neighbours_mean_and_its_own_neighbours_next() {
        let grid = Grid::over(DVec3::ZERO, DVec3::new(4.0, 1.0, 1.0), 1.0).unwrap();
        let value = |v: f32| [[v; 3]; 6];
        let mut faces = vec![value(1.0), value(0.0), value(0.0), value(3.0)];
        let buried = [false, true, true, false];
        fill_buried(&grid, &mut faces, &buried);
        // Probes 1 and 2 each have one open neighbour in the first ring.
        assert_eq!(faces, vec![value(1.0), value(1.0), value(3.0), value(3.0)]);
        let mut lone = vec![value(1.0), value(0.0), value(0.0), value(0.0)];
        fill_buried(&grid, &mut lone, &[false, true, true, true]);
        assert_eq!(lone, vec![value(1.0); 4]);
    }

    #[test]
    fn light_from_one_axis_reaches_only_its_face_and_oblique_light_shares_by_cosine() {
        let mut faces = [DVec3::ZERO; 6];
        add_to_faces(&mut faces, DVec3::Y, DVec3::ONE);
        assert_eq!(faces.map(|f| f.x), [0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        let mut faces = [DVec3::ZERO; 6];
        add_to_faces(&mut faces, DVec3::new(-0.6, 0.0, 0.8), DVec3::ONE);
        assert_eq!(faces.map(|f| f.x), [0.0, 0.6, 0.0, 0.0, 0.8, 0.0]);
    }
}
