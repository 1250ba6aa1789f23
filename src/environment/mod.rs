//! TEMPORARY STAND-IN until the environment branch lands.
use std::path::Path;

#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[f32; 3]>,
}
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightMode {
    Cube { face_size: u32 },
}
impl Default for LightMode {
    fn default() -> Self {
        LightMode::Cube { face_size: 32 }
    }
}
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub direction: [f32; 3],
    pub solid_angle: f32,
    pub radiance: [f32; 3],
}
#[derive(Clone, Debug)]
pub struct LightSet {
    pub lights: Vec<Light>,
    pub mode: LightMode,
    pub map_integral: [f64; 3],
    pub captured: [f64; 3],
    pub dropped: usize,
}
pub struct LoadedEnvironment {
    pub map: EnvironmentMap,
    pub notices: Vec<String>,
}
#[derive(Clone, Debug, Default)]
pub struct EnvLoadOptions {
    pub clamp_nonfinite: bool,
}
impl EnvironmentMap {
    pub fn load(_path: &Path, _o: &EnvLoadOptions) -> anyhow::Result<LoadedEnvironment> {
        anyhow::bail!("stand-in")
    }
    pub fn from_fn(width: u32, height: u32, f: impl Fn([f32; 3]) -> [f32; 3]) -> EnvironmentMap {
        let mut texels = Vec::new();
        for row in 0..height {
            for col in 0..width {
                let phi = ((col as f32 + 0.5) / width as f32 - 0.5) * std::f32::consts::TAU;
                let theta = (row as f32 + 0.5) / height as f32 * std::f32::consts::PI;
                texels.push(f([
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                ]));
            }
        }
        EnvironmentMap {
            width,
            height,
            texels,
        }
    }
    pub fn constant(radiance: [f32; 3]) -> EnvironmentMap {
        Self::from_fn(8, 4, |_| radiance)
    }
    pub fn horizon(radiance: [f32; 3]) -> EnvironmentMap {
        Self::from_fn(64, 32, |d| if d[1] > 0.0 { radiance } else { [0.0; 3] })
    }
}
impl LightSet {
    pub fn extract(
        map: &EnvironmentMap,
        mode: LightMode,
        _rotation_deg: f32,
        _intensity: f32,
    ) -> LightSet {
        let LightMode::Cube { face_size: n } = mode;
        // Sub-sample each pixel; assign to cube texels by direction.
        let s = 16u32;
        let mut energy = vec![[0.0f64; 3]; (6 * n * n) as usize];
        let mut dirs = vec![[0.0f64; 3]; (6 * n * n) as usize];
        for row in 0..map.height {
            for sr in 0..s {
                let t0 = (row * s + sr) as f64 / (map.height * s) as f64 * std::f64::consts::PI;
                let t1 = (row * s + sr + 1) as f64 / (map.height * s) as f64 * std::f64::consts::PI;
                let omega = std::f64::consts::TAU / (map.width * s) as f64 * (t0.cos() - t1.cos());
                let theta = 0.5 * (t0 + t1);
                for col in 0..map.width {
                    let l = map.texels[(row * map.width + col) as usize];
                    for sc in 0..s {
                        let phi = (((col * s + sc) as f64 + 0.5) / (map.width * s) as f64 - 0.5)
                            * std::f64::consts::TAU;
                        let d = [
                            theta.sin() * phi.cos(),
                            theta.cos(),
                            theta.sin() * phi.sin(),
                        ];
                        let (face, u, v) = cube_coords(d);
                        let iu = ((u * n as f64) as u32).min(n - 1);
                        let iv = ((v * n as f64) as u32).min(n - 1);
                        let k = ((face * n + iv) * n + iu) as usize;
                        for c in 0..3 {
                            energy[k][c] += l[c] as f64 * omega;
                            dirs[k][c] += d[c] * omega;
                        }
                    }
                }
            }
        }
        let mut lights = Vec::new();
        let mut captured = [0.0; 3];
        let mut integral = [0.0; 3];
        for k in 0..energy.len() {
            let sa: f64 = dirs[k].iter().map(|x| x * x).sum::<f64>().sqrt();
            for c in 0..3 {
                integral[c] += energy[k][c];
            }
            if energy[k].iter().all(|&e| e == 0.0) {
                continue;
            }
            let omega = 4.0 * std::f64::consts::PI / (6 * n * n) as f64;
            let radiance = energy[k].map(|e| (e / omega) as f32);
            let direction = dirs[k].map(|x| (x / sa) as f32);
            for c in 0..3 {
                captured[c] += radiance[c] as f64 * omega as f32 as f64;
            }
            lights.push(Light {
                direction,
                solid_angle: omega as f32,
                radiance,
            });
        }
        LightSet {
            lights,
            mode,
            map_integral: integral,
            captured,
            dropped: 0,
        }
    }
}
fn cube_coords(d: [f64; 3]) -> (u32, f64, f64) {
    let [x, y, z] = d;
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    let (face, sc, tc, ma) = if ax >= ay && ax >= az {
        if x > 0.0 {
            (0, -z, -y, ax)
        } else {
            (1, z, -y, ax)
        }
    } else if ay >= az {
        if y > 0.0 {
            (2, x, z, ay)
        } else {
            (3, x, -z, ay)
        }
    } else if z > 0.0 {
        (4, x, -y, az)
    } else {
        (5, -x, -y, az)
    };
    (face, 0.5 * (sc / ma + 1.0), 0.5 * (tc / ma + 1.0))
}
impl std::str::FromStr for LightMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.strip_prefix("cube:") {
            Some(n) => n
                .parse()
                .map(|face_size| LightMode::Cube { face_size })
                .map_err(|e| format!("{e}")),
            None => Err(format!("'{s}' is not cube:N")),
        }
    }
}
impl std::fmt::Display for LightMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let LightMode::Cube { face_size } = self;
        write!(f, "cube:{face_size}")
    }
}
