//! Helpers shared by the integration tests: a GPU (a missing adapter fails
//! the test, it never skips), in-memory bakes of fixture scenes, and checks
//! every bake must pass.
#![allow(dead_code)]

use std::path::Path;
use std::sync::Mutex;

use bake::Baked;
use bake::config::BakeOptions;
use bake::environment::{EnvironmentMap, LightMode, LightSet};
use bake::fixtures::{MeshData, SceneBuilder};
use bake::gpu::Gpu;
use bake::progress::Silent;

/// Devices that finished tests handed back, each with the pipelines its bakes
/// built: opening lavapipe and building a bake's pipelines is most of a small
/// bake's time, and a run of several scenes shares them the same way.
static SPARE_GPUS: Mutex<Vec<Gpu>> = Mutex::new(Vec::new());

/// A device for one test at a time: the adapter wgpu picks (lavapipe in CI),
/// a spare one if a finished test left it. Prints its name so a log says what ran.
pub fn gpu() -> TestGpu {
    let spare = SPARE_GPUS.lock().unwrap().pop();
    let gpu =
        spare.unwrap_or_else(|| Gpu::new(None).expect("no GPU adapter: install mesa-vulkan-drivers and libvulkan1"));
    eprintln!("adapter: {}", gpu.adapter);
    TestGpu(Some(gpu))
}

/// A test's device, handed back as a spare when the test is done with it,
/// unless the test failed or left the device lost or with an error unread.
pub struct TestGpu(Option<Gpu>);

impl std::ops::Deref for TestGpu {
    type Target = Gpu;
    fn deref(&self) -> &Gpu {
        self.0.as_ref().expect("held until dropped")
    }
}

impl Drop for TestGpu {
    fn drop(&mut self) {
        let Some(gpu) = self.0.take() else { return };
        if !std::thread::panicking() && gpu.check("a finished test").is_ok() {
            SPARE_GPUS.lock().unwrap().push(gpu);
        }
    }
}

/// Imports a fixture scene from its in-memory GLB.
pub fn scene(builder: &SceneBuilder, name: &str) -> bake::scene::Scene {
    let glb = builder.to_glb();
    let source = bake::asset::SourceAsset::from_bytes(Path::new(&format!("{name}.glb")), &glb, None).unwrap();
    bake::import::from_asset(source).unwrap()
}

/// Options for a small, quick bake: an atlas of at most `atlas` texels.
pub fn options(atlas: u32) -> BakeOptions {
    let mut options = BakeOptions::default();
    options.unwrap.max_atlas_size = atlas;
    options
}

pub fn lights(map: &EnvironmentMap, mode: LightMode) -> LightSet {
    LightSet::extract(map, mode, 0.0, 1.0)
}

/// Bakes `builder` under `lights` and checks the invariants every bake must keep.
pub fn bake(gpu: &Gpu, builder: &SceneBuilder, lights: &LightSet, options: &BakeOptions) -> Baked {
    let baked = bake::bake_scene(gpu, scene(builder, "test"), Some(lights), options, &mut Silent).unwrap();
    assert_valid(&baked);
    baked
}

/// Every texel finite and non-negative, every texel inside the atlas.
pub fn assert_valid(baked: &Baked) {
    assert!(!baked.texels.texels.is_empty(), "the bake covered no texels");
    for (texel, value) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
        assert!(value.iter().all(|c| c.is_finite() && *c >= 0.0), "texel {} has value {value:?}", texel.index);
        assert!(texel.index < baked.texels.width * baked.texels.height);
    }
}

/// The CPU reference's points at texels `indices` of `baked`: each texel's
/// position and shading normal, where its lightmap value belongs.
pub fn reference_points(baked: &Baked, indices: &[usize]) -> Vec<bake::reference::ReferencePoint> {
    indices
        .iter()
        .map(|&i| {
            let t = &baked.texels.texels[i];
            bake::reference::ReferencePoint { position: t.position, normal: t.normal, face_normal: Some(t.face_normal) }
        })
        .collect()
}

/// The lightmap's sum over RGB at each of `texels` beside the reference's
/// estimate there, as (bake, reference).
pub fn against_reference(baked: &Baked, texels: &[usize], estimates: &[bake::reference::Estimate]) -> Vec<(f64, f64)> {
    texels
        .iter()
        .zip(estimates)
        .map(|(&i, e)| (baked.solution.lightmap[i].iter().map(|&v| v as f64).sum(), e.lightmap.iter().sum()))
        .collect()
}

/// Over (bake, reference) pairs: the ratio of their sums, and the RMSE of
/// their differences as a share of the reference's mean.
pub fn ratio_and_rmse(pairs: &[(f64, f64)]) -> (f64, f64) {
    let (bake, expected) = pairs.iter().fold((0.0, 0.0), |(b, r), p| (b + p.0, r + p.1));
    let squares: f64 = pairs.iter().map(|p| (p.0 - p.1).powi(2)).sum();
    let n = pairs.len() as f64;
    (bake / expected, (squares / n).sqrt() / (expected / n))
}

/// Area-weighted mean lightmap (red) of each primitive's texels.
pub fn primitive_means(baked: &Baked) -> Vec<f64> {
    let mut sums = vec![(0.0f64, 0.0f64); baked.scene.primitives.len()];
    for (texel, value) in baked.texels.texels.iter().zip(&baked.solution.lightmap) {
        let sum = &mut sums[texel.primitive as usize];
        sum.0 += value[0] as f64 * texel.area as f64;
        sum.1 += texel.area as f64;
    }
    sums.iter().map(|(v, a)| v / a).collect()
}

/// Lightmap values (red channel) of the texels of primitive `p`, with the texels.
pub fn values_of(baked: &Baked, p: u32) -> Vec<(bake::texelize::Texel, f32)> {
    baked
        .texels
        .texels
        .iter()
        .zip(&baked.solution.lightmap)
        .filter(|(t, _)| t.primitive == p)
        .map(|(t, v)| (*t, v[0]))
        .collect()
}

/// `path` inside the repository.
/// A file of fixtures/.
pub fn fixture(name: &str) -> std::path::PathBuf {
    repo("fixtures").join(name)
}

/// A lightmap EXR's texels, row by row from the top, with its width.
pub fn read_exr(path: &Path) -> (usize, Vec<[f32; 3]>) {
    let exr = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| (size.width(), vec![[0f32; 3]; size.width() * size.height()]),
        |(w, pixels), position, (r, g, b, _a): (f32, f32, f32, f32)| {
            pixels[position.y() * *w + position.x()] = [r, g, b]
        },
    )
    .unwrap();
    exr.layer_data.channel_data.pixels
}

/// The bake binary as a command, for the tests that set more than arguments.
pub fn bake_command() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_bake"))
}

/// Runs the bake binary in `dir` with `args`.
pub fn run_bake(dir: &Path, args: &[&str]) -> std::process::Output {
    bake_command().current_dir(dir).args(args).output().expect("bake runs")
}

/// A tiny bake of `input` into `out` under the sun-and-sky fixture (64²,
/// 64 lights, 64 shots) with `extra`, for the tests that check the files,
/// not the light.
pub fn tiny_bake(input: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    tiny_bake_all(&[input], out, extra)
}

/// As `tiny_bake`, for several inputs in one run (one start-up).
pub fn tiny_bake_all(inputs: &[&Path], out: &Path, extra: &[&str]) -> std::process::Output {
    let env = repo("fixtures/sky_sun.exr");
    bake_command()
        .args(inputs)
        .args(["--env".as_ref(), env.as_os_str(), "-o".as_ref(), out.as_os_str()])
        .args(["--max-atlas-size", "64", "--lights", "64", "--max-shots", "64", "-q"])
        .args(extra)
        .output()
        .expect("bake runs")
}

/// A run's stderr as text.
pub fn stderr(output: &std::process::Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

pub fn repo(path: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// Runs a Node script of pipeline/ with `args` and returns its stdout; fails
/// the test with its output when it fails (its npm packages come from
/// ./pipeline/setup.sh).
pub fn node(script: &str, args: &[&std::ffi::OsStr]) -> String {
    let run = std::process::Command::new("node")
        .arg(repo(script))
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run node ({e}): {script} needs Node.js; run ./pipeline/setup.sh"));
    assert!(
        run.status.success(),
        "{script} {args:?} failed (run ./pipeline/setup.sh to install its packages): {}{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    String::from_utf8(run.stdout).expect("the script writes UTF-8")
}

/// Bakes `input` through the CLI under the sun-and-sky fixture with `args`
/// into `out`; fails the test on a failed bake, else returns its report.
pub fn bake_file(input: &Path, out: &Path, args: &[&str]) -> bake::report::Report {
    bake_files(&[input], out, args)
}

/// As `bake_file`, for several inputs in one run (one report, a scene each).
pub fn bake_files(inputs: &[&Path], out: &Path, args: &[&str]) -> bake::report::Report {
    let env = repo("fixtures/sky_sun.exr");
    let output = bake_command()
        .args(inputs)
        .args(["--env".as_ref(), env.as_os_str(), "-o".as_ref(), out.as_os_str()])
        .args(args)
        .output()
        .expect("bake runs");
    assert!(output.status.success(), "bake {inputs:?}: {}", String::from_utf8_lossy(&output.stderr));
    serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap()
}

/// Mean L_lm on a grey 8 m ground (under the canopy's −X half, under its
/// +X half, in the open) beneath a 4 m canopy 1 m up, facing down, under a
/// sun overhead. The canopy's base colour texture is `texture`'s (one whose
/// alpha holds its left half, u < 0.5, opaque, lies over −X); `alpha` sets
/// its alpha mode.
pub fn ground_under_a_canopy(
    texture: &dyn Fn(&mut SceneBuilder) -> usize,
    alpha: &dyn Fn(&mut SceneBuilder, usize),
) -> (f32, f32, f32) {
    use bake::fixtures::{MeshData, Placement};
    use glam::{Quat, Vec3};
    let gpu = gpu();
    let mut builder = SceneBuilder::new();
    builder.object("ground", &MeshData::plane(8.0, 8.0, 4), [0.5, 0.5, 0.5, 1.0], [0.0; 3], Placement::default());
    let canopy = builder.material("canopy", [0.5, 0.5, 0.5, 1.0], [0.0; 3]);
    let t = texture(&mut builder);
    builder.base_color_texture(canopy, t, None);
    alpha(&mut builder, canopy);
    let mesh = builder.mesh("canopy", &MeshData::plane(4.0, 4.0, 2), Some(canopy));
    let over = Placement::at(Vec3::new(0.0, 1.0, 0.0)).rotated(Quat::from_rotation_x(180f32.to_radians()));
    builder.node("canopy", mesh, over);
    let sun = EnvironmentMap::from_fn(512, 256, |d| if d[1] > 0.999 { [1000.0; 3] } else { [0.0; 3] });
    let lights = lights(&sun, LightMode::Budget { count: 16 });
    let baked = bake(&gpu, &builder, &lights, &options(128));
    let ground = values_of(&baked, 0);
    let mean = |inside: &dyn Fn(Vec3) -> bool| {
        let v: Vec<f32> = ground.iter().filter(|(t, _)| inside(t.position())).map(|(_, v)| *v).collect();
        v.iter().sum::<f32>() / v.len() as f32
    };
    let under_left = mean(&|p| p.x < -0.5 && p.x > -1.5 && p.z.abs() < 1.5);
    let under_right = mean(&|p| p.x > 0.5 && p.x < 1.5 && p.z.abs() < 1.5);
    (under_left, under_right, mean(&|p| p.x.abs() > 3.0))
}

/// A KTX2 file as bake writes it (a lightmap, or a probe volume): its
/// width, height, depth (0 for a 2D image) and texels (row by row from the
/// first, slice by slice), after checking its header and data format
/// descriptor.
pub fn read_ktx2(bytes: &[u8]) -> (usize, usize, usize, Vec<[f32; 3]>) {
    use ::ktx2::{ColorModel, ColorPrimaries, Format, SupercompressionScheme, TransferFunction};
    let reader = ::ktx2::Reader::new(bytes).expect("the ktx2 crate reads it");
    let header = reader.header();
    assert_eq!(header.format, Some(Format::E5B9G9R9_UFLOAT_PACK32));
    assert_eq!((header.type_size, header.layer_count, header.face_count), (4, 0, 1));
    assert_eq!(header.level_count, 1, "one mip level");
    assert_eq!(header.supercompression_scheme, Some(SupercompressionScheme::Zstandard));
    let dfd = reader.basic_dfd().expect("a basic descriptor block");
    assert_eq!(reader.dfd_blocks().len(), 1);
    assert_eq!(dfd.color_model, Some(ColorModel::RGBSDA));
    assert_eq!(dfd.color_primaries, Some(ColorPrimaries::BT709));
    assert_eq!(dfd.transfer_function, Some(TransferFunction::Linear), "linear, not sRGB");
    assert_eq!(dfd.bytes_planes[0], 4);
    // R, G, B mantissas at bits 0, 9 and 18, each with the exponent at 27.
    let samples: Vec<(u16, u8, u8)> =
        dfd.sample_information.iter().map(|s| (s.bit_offset, s.bit_length.get(), s.channel_type)).collect();
    assert_eq!(samples, [(0, 9, 0), (27, 5, 0), (9, 9, 1), (27, 5, 1), (18, 9, 2), (27, 5, 2)]);
    assert!(reader.writer().is_some_and(|w| w.starts_with("bake ")), "{:?}", reader.writer());
    let (width, height, depth) =
        (header.pixel_width as usize, header.pixel_height as usize, header.pixel_depth as usize);
    let level = reader.levels().next().unwrap();
    assert_eq!(level.uncompressed_byte_length as usize, width * height * depth.max(1) * 4);
    let mut texels = Vec::new();
    let mut decoder = ruzstd::decoding::StreamingDecoder::new(level.data).expect("a Zstandard frame");
    std::io::Read::read_to_end(&mut decoder, &mut texels).expect("the level decompresses");
    assert_eq!(texels.len(), width * height * depth.max(1) * 4);
    let unpack = |t: &[u8]| bake::export::ktx2::unpack_e5b9g9r9(u32::from_le_bytes(t.try_into().unwrap()));
    (width, height, depth, texels.chunks_exact(4).map(unpack).collect())
}

/// The triangles of `sphere` whose centroid `keep` accepts, turned to face
/// the sphere's inside.
pub fn inside_of(sphere: &MeshData, keep: impl Fn(glam::Vec3) -> bool) -> MeshData {
    let mut part = MeshData::default();
    for triangle in sphere.indices.chunks(3) {
        let corner = |k: usize| glam::Vec3::from(sphere.positions[triangle[k] as usize]);
        if !keep((corner(0) + corner(1) + corner(2)) / 3.0) {
            continue;
        }
        for &i in &[triangle[0], triangle[2], triangle[1]] {
            part.indices.push(part.positions.len() as u32);
            part.positions.push(sphere.positions[i as usize]);
            part.normals.push((-glam::Vec3::from(sphere.normals[i as usize])).to_array());
            part.uv0.push(sphere.uv0[i as usize]);
        }
    }
    part
}

/// A 64×64 image whose left half (u < 0.5) is `left` and right half `right`.
pub fn halves(left: [u8; 4], right: [u8; 4]) -> image::RgbaImage {
    image::RgbaImage::from_fn(64, 64, |x, _| image::Rgba(if x < 32 { left } else { right }))
}
