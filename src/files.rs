//! Opening and reading input files: regular files only, their size known
//! before a byte is read. A FIFO would block the run until someone writes
//! to it, and a device such as `/dev/zero` never ends; both are refused with
//! an error that says what the path is (symbolic links are followed first).

use std::fs::{File, OpenOptions};
use std::io::{self, Read};
use std::path::Path;

/// Opens `path` for reading if it is a regular file, with its length in bytes.
pub fn open(path: &Path) -> io::Result<(File, u64)> {
    let mut options = OpenOptions::new();
    options.read(true);
    // Opening a FIFO blocks until a writer comes, before any check could run;
    // non-blocking, it opens at once. It changes nothing for a regular file.
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut options, libc::O_NONBLOCK);
    let file = options.open(path)?;
    // The type of what was opened, not of what the path named a moment before.
    let metadata = file.metadata()?;
    if !metadata.is_file() {
        let message = format!("{}, not a regular file", describe(&metadata.file_type()));
        return Err(io::Error::new(io::ErrorKind::InvalidInput, message));
    }
    Ok((file, metadata.len()))
}

/// Whether `path`, resolved through symbolic links, lies in `folder` (an
/// empty path is the current folder): a link inside a folder may point
/// anywhere. A path that does not resolve (a missing file) counts as inside,
/// left for its read to report.
pub fn resolves_inside(path: &Path, folder: &Path) -> bool {
    let folder = if folder.as_os_str().is_empty() { Path::new(".") } else { folder };
    match (path.canonicalize(), folder.canonicalize()) {
        (Ok(resolved), Ok(folder)) => resolved.starts_with(folder),
        _ => true,
    }
}

/// The whole of a regular file, reading no more than the length it had when opened.
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    let (file, length) = open(path)?;
    let mut bytes = Vec::with_capacity(usize::try_from(length).unwrap_or(0));
    file.take(length).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Refuses an image whose header declares `width`×`height` texels of
/// `bytes_per_texel` decoded bytes each when a file of `length` bytes cannot
/// hold them: at most `ratio` decoded bytes per byte, the format's densest
/// coding. Checked before anything is allocated for the texels.
pub fn check_declared(width: u64, height: u64, bytes_per_texel: u64, length: u64, ratio: u64) -> Result<(), String> {
    // In u128, so that the figure shown is the true one for any 32-bit width and height.
    let decoded = u128::from(width).saturating_mul(u128::from(height)).saturating_mul(u128::from(bytes_per_texel));
    if decoded > u128::from(length) * u128::from(ratio) {
        return Err(format!(
            "the header declares {width}×{height} texels ({decoded} bytes decoded), more than the file's {length} \
             bytes can hold"
        ));
    }
    Ok(())
}

fn describe(kind: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return "it is a FIFO (named pipe)";
        }
        if kind.is_char_device() || kind.is_block_device() {
            return "it is a device";
        }
        if kind.is_socket() {
            return "it is a socket";
        }
    }
    if kind.is_dir() { "it is a folder" } else { "it is a special file" }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_folders_are_refused_and_files_read() {
        let error = read(Path::new("/dev/zero")).unwrap_err().to_string();
        assert_eq!(error, "it is a device, not a regular file");
        let error = read(Path::new("/")).unwrap_err().to_string();
        assert_eq!(error, "it is a folder, not a regular file");
        assert_eq!(read(Path::new(file!())).unwrap(), std::fs::read(file!()).unwrap());
    }
}
