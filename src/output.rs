//! Atomic outputs: a run writes everything into a staging folder and moves
//! the files into the output folder only when the whole run succeeded, each
//! by a rename. A failed run leaves the output folder as it was (and does
//! not create it); inputs are never written.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use anyhow::{Context, Result, bail};

/// The name of a run's staging folder: the prefix and the run's process id.
const STAGING_PREFIX: &str = ".bake-staging-";

/// The most an output's name adds to its input's stem ('.image4294967295.jpeg'
/// in the `.gltf` form; '.lightmap0.ktx2' in a `.glb` bake).
const LONGEST_SUFFIX: usize = 24;

/// This process's staging folders, for the signal handler to remove.
static ACTIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn active() -> MutexGuard<'static, Vec<PathBuf>> {
    ACTIVE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Removes this run's staging folders when SIGINT or SIGTERM ends it, then
/// exits with 128 + the signal, as a shell reports it. SIGKILL cannot be
/// caught: the next run into the same folder removes what it left.
pub fn remove_staging_on_signals() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else { return };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            // Holding the lock until exit: a commit under way finishes first, and no new folder appears.
            let mut dirs = active();
            for dir in dirs.drain(..) {
                let _ = std::fs::remove_dir_all(dir);
            }
            std::process::exit(128 + signal);
        }
    });
}

/// The file in a staging folder its run holds locked while it lasts.
const LOCK: &str = ".lock";

/// Refuses, before the bake, an input whose outputs' names would be longer
/// than the folder they are staged in takes (255 bytes on most filesystems).
fn refuse_long_names(parent: &Path, inputs: &[PathBuf]) -> Result<()> {
    let most = name_max(parent);
    for input in inputs {
        let stem = input.file_stem().map_or(0, |s| s.as_encoded_bytes().len());
        if stem + LONGEST_SUFFIX > most {
            bail!(
                "input '{}': its name is {stem} bytes before the extension; its outputs add up to {LONGEST_SUFFIX} \
                 more, past the {most} bytes a file name may have in '{}'; rename it",
                input.display(),
                parent.display()
            );
        }
    }
    Ok(())
}

/// The longest file name `folder`'s filesystem takes, in bytes (255 where
/// it does not say).
fn name_max(folder: &Path) -> usize {
    #[cfg(unix)]
    if let Ok(path) = std::ffi::CString::new(folder.as_os_str().as_encoded_bytes()) {
        // SAFETY: `path` is a NUL-terminated string that outlives the call.
        let most = unsafe { libc::pathconf(path.as_ptr(), libc::_PC_NAME_MAX) };
        if most > 0 {
            return most as usize;
        }
    }
    255
}

/// Removes the staging folders in `parent` whose run is gone (killed, or the
/// machine went down), so they do not pile up in an output folder. A run
/// holds its folder's lock file locked (released by the kernel when the
/// process ends, whatever ends it); a folder without one is judged by its
/// process id, which another PID namespace or host may reuse.
fn remove_stale(parent: &Path) {
    let Ok(entries) = std::fs::read_dir(parent) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(suffix) = name.to_str().and_then(|n| n.strip_prefix(STAGING_PREFIX)) else { continue };
        let lock = std::fs::File::open(entry.path().join(LOCK)).ok();
        let stale = match &lock {
            Some(lock) => lock.try_lock().is_ok(),
            None => {
                let pid = suffix.split('-').next().and_then(|p| p.parse::<u32>().ok());
                pid.is_some_and(|pid| !process_exists(pid))
            }
        };
        if stale {
            // Still holding the lock, so that no run takes the folder meanwhile.
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// A staging folder of this run's own in `parent`, named after the process
/// (and a count where another run, in another PID namespace or on another
/// host, has that name), with its lock file locked.
fn make_staging(parent: &Path) -> Result<(PathBuf, std::fs::File)> {
    let pid = std::process::id();
    for n in 0u32.. {
        let name = if n == 0 { format!("{STAGING_PREFIX}{pid}") } else { format!("{STAGING_PREFIX}{pid}-{n}") };
        let dir = parent.join(name);
        match std::fs::create_dir(&dir) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && n < 1000 => continue,
            Err(e) => return Err(e).with_context(|| format!("cannot create staging folder '{}'", dir.display())),
        }
        let lock = std::fs::File::create(dir.join(LOCK))
            .and_then(|lock| lock.lock().map(|()| lock))
            .with_context(|| format!("cannot lock staging folder '{}'", dir.display()));
        if lock.is_err() {
            let _ = std::fs::remove_dir_all(&dir);
        }
        return Ok((dir, lock?));
    }
    unreachable!("the loop returns by its thousandth name")
}

#[cfg(target_os = "linux")]
fn process_exists(pid: u32) -> bool {
    Path::new("/proc").join(pid.to_string()).exists()
}

/// Elsewhere a folder is never taken for stale.
#[cfg(not(target_os = "linux"))]
fn process_exists(_: u32) -> bool {
    true
}

/// A staging folder for one run's outputs.
pub struct Staging {
    dir: PathBuf,
    /// Its lock file, locked while the run lasts (`remove_stale`).
    _lock: std::fs::File,
    output: PathBuf,
    /// Input files (canonical paths) no output may replace.
    protected: Vec<PathBuf>,
    committed: bool,
}

impl Staging {
    /// Checks that the inputs' outputs cannot collide with each other or
    /// overwrite an input, and makes the staging folder.
    pub fn new(output: &Path, inputs: &[PathBuf]) -> Result<Staging> {
        let mut names = HashSet::new();
        for input in inputs {
            let stem = input.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            if !names.insert(stem.clone()) {
                bail!(
                    "two inputs are named '{stem}': their outputs would overwrite each other; bake them into different folders"
                );
            }
            for produced in [format!("{stem}.glb"), format!("{stem}.lightmap0.exr"), format!("{stem}.lightmap0.ktx2")] {
                let target = output.join(&produced);
                if same_file(&target, input) {
                    bail!(
                        "input '{}': the output '{}' would replace it; choose another -o folder",
                        input.display(),
                        target.display()
                    );
                }
            }
        }
        if output.exists() && !output.is_dir() {
            bail!("output '{}' exists and is not a folder", output.display());
        }
        let parent = if output.is_dir() {
            output.to_path_buf()
        } else {
            match output.parent().filter(|p| p.as_os_str().is_empty() || p.is_dir()) {
                Some(parent) if parent.as_os_str().is_empty() => PathBuf::from("."),
                Some(parent) => parent.to_path_buf(),
                None => std::env::temp_dir(),
            }
        };
        refuse_long_names(&parent, inputs)?;
        remove_stale(&parent);
        let mut dirs = active();
        let (dir, lock) = make_staging(&parent)?;
        dirs.push(dir.clone());
        let protected = inputs.iter().filter_map(|p| p.canonicalize().ok()).collect();
        Ok(Staging { dir, _lock: lock, output: output.to_path_buf(), protected, committed: false })
    }

    /// Adds files an input consists of (its external buffers and images, the
    /// environment map):
    /// `commit` refuses to replace any of them.
    pub fn protect(&mut self, files: impl IntoIterator<Item = PathBuf>) {
        self.protected.extend(files.into_iter().filter_map(|p| p.canonicalize().ok()));
    }

    /// Where stages write their files.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Where a staged file ends up after `commit`.
    pub fn final_path(&self, staged: &Path) -> PathBuf {
        self.output.join(staged.file_name().unwrap_or_default())
    }

    /// Moves every staged file into the output folder (replacing older ones),
    /// after checking that none would replace an input file or a folder. A
    /// failure part way puts back the files already replaced.
    pub fn commit(mut self) -> Result<()> {
        // A signal now waits for the files to be moved.
        let _moving = active();
        let created = !self.output.exists();
        std::fs::create_dir_all(&self.output)
            .with_context(|| format!("cannot create output folder '{}'", self.output.display()))?;
        let mut entries: Vec<PathBuf> = std::fs::read_dir(&self.dir)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|path| path.file_name() != Some(std::ffi::OsStr::new(LOCK)))
            .collect();
        entries.sort();
        for staged in &entries {
            let target = self.final_path(staged);
            if let Ok(canonical) = target.canonicalize()
                && self.protected.contains(&canonical)
            {
                bail!("the output '{}' would replace a file of an input; choose another -o folder", target.display());
            }
            refuse_folder(&target)?;
        }
        if let Err(e) = place_all(&entries, &self.output, &self.dir.join(REPLACED)) {
            if created {
                let _ = std::fs::remove_dir(&self.output);
            }
            return Err(e);
        }
        self.committed = true;
        let _ = std::fs::remove_dir_all(&self.dir);
        Ok(())
    }
}

/// Where `commit` keeps the files it replaces until every file is in place.
const REPLACED: &str = ".replaced";

/// An output never replaces a folder.
fn refuse_folder(target: &Path) -> Result<()> {
    if target.symlink_metadata().is_ok_and(|m| m.is_dir()) {
        bail!("the output '{}' is a folder; move it or choose another -o folder", target.display());
    }
    Ok(())
}

/// Moves each of `staged` into `output`, first moving the file it replaces
/// (if any) into `replaced`. On a failure every file is put back as it was.
fn place_all(staged: &[PathBuf], output: &Path, replaced: &Path) -> Result<()> {
    // (target, where the file it replaced waits)
    let mut placed: Vec<(PathBuf, Option<PathBuf>)> = Vec::new();
    for file in staged {
        let name = file.file_name().unwrap_or_default();
        let target = output.join(name);
        match place(file, &target, &replaced.join(name)) {
            Ok(old) => placed.push((target, old)),
            Err(e) => {
                for (target, old) in placed.iter().rev() {
                    let _ = std::fs::remove_file(target);
                    if let Some(old) = old {
                        let _ = std::fs::rename(old, target);
                    }
                }
                return Err(e);
            }
        }
    }
    Ok(())
}

/// Moves `staged` to `target`, the file there (never a folder) first to
/// `aside`, which it returns; on a failure the old file is back in place.
fn place(staged: &Path, target: &Path, aside: &Path) -> Result<Option<PathBuf>> {
    refuse_folder(target)?;
    let old = if target.symlink_metadata().is_ok() {
        std::fs::create_dir_all(aside.parent().unwrap_or(aside))
            .and_then(|_| std::fs::rename(target, aside))
            .with_context(|| format!("replacing '{}'", target.display()))?;
        Some(aside.to_path_buf())
    } else {
        None
    };
    if let Err(e) = move_file(staged, target) {
        if let Some(old) = &old {
            let _ = std::fs::rename(old, target);
        }
        return Err(e);
    }
    Ok(old)
}

fn move_file(staged: &Path, target: &Path) -> Result<()> {
    if std::fs::rename(staged, target).is_ok() {
        return Ok(());
    }
    // A different filesystem: copy beside the target, then rename there.
    let mut partial = target.as_os_str().to_owned();
    partial.push(".partial");
    let partial = PathBuf::from(partial);
    let moved = std::fs::copy(staged, &partial).and_then(|_| std::fs::rename(&partial, target));
    if moved.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    moved.with_context(|| format!("writing '{}'", target.display()))
}

impl Drop for Staging {
    fn drop(&mut self) {
        active().retain(|dir| dir != &self.dir);
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_placement_puts_back_the_files_it_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let (staging, output) = (dir.path().join("staging"), dir.path().join("out"));
        std::fs::create_dir_all(&staging).unwrap();
        std::fs::create_dir_all(output.join("b.bin")).unwrap();
        for (name, bytes) in [("a.bin", "new a"), ("b.bin", "new b"), ("c.bin", "new c")] {
            std::fs::write(staging.join(name), bytes).unwrap();
        }
        std::fs::write(output.join("a.bin"), "old a").unwrap();
        let staged: Vec<PathBuf> = ["a.bin", "b.bin", "c.bin"].iter().map(|n| staging.join(n)).collect();
        let error = place_all(&staged, &output, &staging.join(REPLACED)).unwrap_err();
        assert!(format!("{error}").contains("is a folder"), "{error}");
        assert_eq!(std::fs::read_to_string(output.join("a.bin")).unwrap(), "old a");
        assert!(output.join("b.bin").is_dir());
        let mut left: Vec<_> = std::fs::read_dir(&output).unwrap().map(|e| e.unwrap().file_name()).collect();
        left.sort();
        assert_eq!(left, ["a.bin", "b.bin"]);
    }

    #[test]
    fn a_placement_replaces_older_files() {
        let dir = tempfile::tempdir().unwrap();
        let (staging, output) = (dir.path().join("staging"), dir.path().join("out"));
        std::fs::create_dir_all(&staging).unwrap();
        std::fs::create_dir_all(&output).unwrap();
        std::fs::write(staging.join("a.bin"), "new a").unwrap();
        std::fs::write(output.join("a.bin"), "old a").unwrap();
        place_all(&[staging.join("a.bin")], &output, &staging.join(REPLACED)).unwrap();
        assert_eq!(std::fs::read_to_string(output.join("a.bin")).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(staging.join(REPLACED).join("a.bin")).unwrap(), "old a");
    }
}
