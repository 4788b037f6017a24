//! Files the product replaces whole (the calibration state, the installer
//! snapshot): written to `PATH.stature-tmp` beside the target and renamed
//! over it, so that a reader or a power cut sees the old file or the new
//! one. The suffix is the product's own: `PATH.tmp` may be someone's file
//! (`--state notes` must not truncate `notes.tmp`).
//!
//! A rename replaces whatever is at the path. Two cases must not be
//! replaced: a symbolic link (an installer who points `--state` at a file
//! on persistent storage expects that file to be updated, not the link to
//! become a copy) and anything that is not a regular file (`/dev/null`, a
//! FIFO, a device). [`target`] follows links and refuses the rest.

use std::io;
use std::path::{Path, PathBuf};

/// Links followed before giving up (the kernel's own limit is 40).
const MAX_LINKS: usize = 40;

/// The path a replacement of `path` must be renamed to: `path` itself, or
/// the file at the end of its chain of symbolic links (which need not
/// exist yet). Fails when that exists and is not a regular file, or the
/// chain does not end.
pub fn target(path: &Path) -> io::Result<PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        let meta = match std::fs::symlink_metadata(&p) {
            Ok(m) => m,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(p),
            Err(e) => return Err(e),
        };
        if meta.file_type().is_symlink() {
            let to = std::fs::read_link(&p)?;
            p = match p.parent() {
                Some(dir) if to.is_relative() => dir.join(to),
                _ => to,
            };
            continue;
        }
        if meta.is_dir() {
            return Err(io::Error::other("it is a directory"));
        }
        if !meta.is_file() {
            return Err(io::Error::other(
                "not a regular file (it would be replaced by one on every write)",
            ));
        }
        return Ok(p);
    }
    Err(io::Error::other("too many levels of symbolic links"))
}

/// `PATH.stature-tmp`: the temporary file beside `path`.
pub fn tmp_beside(path: &Path) -> PathBuf {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".stature-tmp");
    PathBuf::from(tmp)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("stature-replace-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn plain_and_missing_paths_are_their_own_target() {
        let d = scratch("plain");
        let f = d.join("a.state");
        assert_eq!(target(&f).unwrap(), f);
        std::fs::write(&f, b"x").unwrap();
        assert_eq!(target(&f).unwrap(), f);
        assert_eq!(tmp_beside(&f), d.join("a.state.stature-tmp"));
    }

    #[cfg(unix)]
    #[test]
    fn links_are_followed_to_their_file() {
        let d = scratch("links");
        std::fs::create_dir_all(d.join("real")).unwrap();
        // Relative link to a file that does not exist yet, then a link to that link.
        std::os::unix::fs::symlink("real/t.state", d.join("one")).unwrap();
        std::os::unix::fs::symlink(d.join("one"), d.join("two")).unwrap();
        assert_eq!(target(&d.join("one")).unwrap(), d.join("real/t.state"));
        assert_eq!(target(&d.join("two")).unwrap(), d.join("real/t.state"));
        // A loop never ends.
        std::os::unix::fs::symlink(d.join("loop_b"), d.join("loop_a")).unwrap();
        std::os::unix::fs::symlink(d.join("loop_a"), d.join("loop_b")).unwrap();
        assert!(target(&d.join("loop_a")).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn devices_and_directories_are_refused() {
        let e = target(Path::new("/dev/null")).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let d = scratch("dir");
        assert!(target(&d).unwrap_err().to_string().contains("directory"));
        // Through a link too.
        std::os::unix::fs::symlink("/dev/null", d.join("null")).unwrap();
        assert!(target(&d.join("null")).is_err());
    }
}
