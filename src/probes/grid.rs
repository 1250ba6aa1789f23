//! Where the probes stand: a box cut into equal cells, one probe at the
//! centre of each, as Bevy's `IrradianceVolume` places its voxels (a unit
//! cube stretched over the box, each texel at a cell's centre).

use anyhow::{Result, bail};
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Most probes one scene may ask for: beyond it a spacing is almost
/// certainly a unit mistake (millimetres for metres), and the volume would
/// not fit an engine's 3D texture.
pub const MAX_PROBES: u64 = 1 << 21;
/// Most probes along x, y and z: Bevy's volume texture is (x, 2·y, 3·z)
/// texels, and a 3D texture is at most 2048 wide on most GPUs (WebGPU's
/// and wgpu's default limit).
pub const MAX_COUNTS: [u32; 3] = [2048, 1024, 682];

/// A box of `counts` cells, world coordinates (metres).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    pub min: [f64; 3],
    pub max: [f64; 3],
    /// Probes along x, y and z.
    pub counts: [u32; 3],
}

impl Grid {
    /// Cells no wider than `spacing` over `min..max`; an axis the box is
    /// flat along gets one cell `spacing` thick, its probe in the plane.
    pub fn over(min: DVec3, max: DVec3, spacing: f64) -> Result<Grid> {
        if !(spacing > 0.0 && spacing.is_finite()) {
            bail!("probe spacing {spacing} is not a positive length");
        }
        if !(min.is_finite() && max.is_finite() && min.cmple(max).all()) {
            bail!("probe box {min}..{max} is not a box");
        }
        let flat = (max - min).cmple(DVec3::ZERO);
        let half = DVec3::splat(spacing / 2.0);
        let (min, max) = (DVec3::select(flat, min - half, min), DVec3::select(flat, max + half, max));
        // Less than a part in 10⁹ over a whole number of spacings is that number.
        let cells = ((max - min) / spacing - 1e-9).ceil().max(DVec3::ONE);
        let total = cells.x * cells.y * cells.z;
        if total > MAX_PROBES as f64 {
            bail!(
                "a probe spacing of {spacing} m over a {:.3} × {:.3} × {:.3} m box makes {total:.0} probes, more than \
                 {MAX_PROBES}: raise --probes",
                max.x - min.x,
                max.y - min.y,
                max.z - min.z
            );
        }
        let counts = cells.to_array().map(|c| c as u32);
        if let Some(axis) = (0..3).find(|&k| counts[k] > MAX_COUNTS[k]) {
            bail!(
                "a probe spacing of {spacing} m makes {} probes along {}, more than the {} an engine's 3D texture \
                 holds: raise --probes or narrow --probe-box",
                counts[axis],
                ["x", "y", "z"][axis],
                MAX_COUNTS[axis]
            );
        }
        Ok(Grid { min: min.to_array(), max: max.to_array(), counts })
    }

    pub fn len(&self) -> usize {
        self.counts.iter().map(|&c| c as usize).product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Probe `i`'s cell along each axis, x fastest, then y, then z.
    pub fn cell(&self, i: usize) -> [u32; 3] {
        let [nx, ny, _] = self.counts.map(|c| c as usize);
        [i % nx, (i / nx) % ny, i / (nx * ny)].map(|c| c as u32)
    }

    /// The index of the probe in cell `c`.
    pub fn index(&self, c: [u32; 3]) -> usize {
        let [nx, ny, _] = self.counts.map(|c| c as usize);
        c[0] as usize + nx * (c[1] as usize + ny * c[2] as usize)
    }

    /// Probe `i`'s world position: its cell's centre.
    pub fn position(&self, i: usize) -> DVec3 {
        let (min, max) = (DVec3::from(self.min), DVec3::from(self.max));
        let counts = DVec3::from(self.counts.map(f64::from));
        let cell = DVec3::from(self.cell(i).map(f64::from));
        min + (max - min) * (cell + 0.5) / counts
    }

    /// The box's centre and size: the translation and scale of a Transform
    /// that stretches Bevy's unit-cube volume over it.
    pub fn centre_and_size(&self) -> ([f64; 3], [f64; 3]) {
        let (min, max) = (DVec3::from(self.min), DVec3::from(self.max));
        (((min + max) / 2.0).to_array(), (max - min).to_array())
    }

    /// The distance between neighbouring probes along each axis.
    pub fn spacing(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| (self.max[k] - self.min[k]) / f64::from(self.counts[k]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probes_sit_at_cell_centres_no_further_apart_than_asked() {
        let grid = Grid::over(DVec3::new(-1.0, 0.0, 2.0), DVec3::new(1.0, 0.5, 2.0), 0.3).unwrap();
        assert_eq!(grid.counts, [7, 2, 1]);
        let flat = [grid.min[2] - 1.85, grid.max[2] - 2.15];
        assert!(flat.iter().all(|d| d.abs() < 1e-12), "a flat axis is one spacing thick: {flat:?}");
        assert!(grid.spacing().iter().all(|&s| s <= 0.3));
        let first = grid.position(0);
        assert!((first - DVec3::new(-1.0 + 1.0 / 7.0, 0.125, 2.0)).length() < 1e-12, "{first}");
        let last = grid.position(grid.len() - 1);
        assert!((last - DVec3::new(1.0 - 1.0 / 7.0, 0.375, 2.0)).length() < 1e-12, "{last}");
        for i in 0..grid.len() {
            assert_eq!(grid.index(grid.cell(i)), i);
        }
    }

    #[test]
    fn a_spacing_that_makes_too_many_probes_or_none_is_refused() {
        let unit = DVec3::ONE;
        assert!(Grid::over(DVec3::ZERO, unit * 1000.0, 0.001).unwrap_err().to_string().contains("raise --probes"));
        assert!(Grid::over(DVec3::ZERO, unit, 0.0).is_err());
        assert!(Grid::over(DVec3::ZERO, unit, f64::NAN).is_err());
        assert!(Grid::over(unit, DVec3::ZERO, 1.0).is_err());
        // Few probes in all, but too many along one axis for a 3D texture.
        let long = Grid::over(DVec3::ZERO, DVec3::new(0.0, 0.0, 700.0), 1.0).unwrap_err().to_string();
        assert!(long.contains("700 probes along z"), "{long}");
        assert!(Grid::over(DVec3::ZERO, DVec3::new(0.0, 0.0, 682.0), 1.0).is_ok());
    }
}
