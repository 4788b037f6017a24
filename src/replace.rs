//! Files the product replaces whole (the calibration state, the installer
//! snapshot, the trained weights and their report): written to
//! `PATH.stature-tmp` (or, while another process writes that one,
//! `PATH.stature-tmp.PID`) beside the target and renamed over it, so that a reader or a power cut sees the old file or the new
//! one. The suffix is the product's own: `PATH.tmp` may be someone's file
//! (`--state notes` must not truncate `notes.tmp`).
//!
//! A rename replaces whatever is at the path. Two cases must not be
//! replaced: a symbolic link (an installer who points `--state` at a file
//! on persistent storage expects that file to be updated, not the link to
//! become a copy) and anything that is not a regular file (`/dev/null`, a
//! FIFO, a device). [`target`] follows links and refuses the rest.
//!
//! The files the product reads whole (state, config, weights) are read
//! with [`read_capped`], never past a size no valid file reaches.

use std::io;
use std::path::{Path, PathBuf};

/// Links followed before giving up (the kernel's own limit is 40).
const MAX_LINKS: usize = 40;

/// The path a replacement of `path` must be renamed to: `path` itself, or
/// the file at the end of its chain of symbolic links (which need not
/// exist yet). Fails when that exists and is not a regular file, or the
/// chain does not end.
pub fn target(path: &Path) -> io::Result<PathBuf> {
    let (p, meta) = follow_links(path)?;
    match meta {
        Some(m) if m.is_dir() => Err(io::Error::other("it is a directory")),
        Some(m) if !m.is_file() => Err(io::Error::other(
            "not a regular file (it would be replaced by one on every write)",
        )),
        _ => Ok(p),
    }
}

/// The end of `path`'s chain of symbolic links, with its metadata, or
/// `None` when nothing is there yet (a dangling link's target: the file
/// a write through the link creates). Fails when the chain does not end.
pub fn follow_links(path: &Path) -> io::Result<(PathBuf, Option<std::fs::Metadata>)> {
    let mut p = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        let meta = match std::fs::symlink_metadata(&p) {
            Ok(m) => m,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok((p, None)),
            Err(e) => return Err(e),
        };
        if !meta.file_type().is_symlink() {
            return Ok((p, Some(meta)));
        }
        let to = std::fs::read_link(&p)?;
        p = match p.parent() {
            Some(dir) if to.is_relative() => dir.join(to),
            _ => to,
        };
    }
    Err(io::Error::other("too many levels of symbolic links"))
}

/// The directory `path` is in: its parent, or `.` for a bare file name.
pub fn dir_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// `e`, the failure to create `path`, or, when it failed because the
/// directory `path` would go in does not exist, an error that says so:
/// "No such file or directory" alone reads as if the file itself were
/// expected to be there (an installer who forgot `mkdir /var/lib/stature`).
pub fn name_missing_dir(path: &Path, e: io::Error) -> io::Error {
    let dir = dir_of(path);
    let missing = e.kind() == io::ErrorKind::NotFound
        && std::fs::metadata(dir).is_err_and(|m| m.kind() == io::ErrorKind::NotFound);
    if missing {
        io::Error::new(
            e.kind(),
            format!("directory {} does not exist", dir.display()),
        )
    } else {
        e
    }
}

/// `PATH.stature-tmp`: the temporary file beside `path`.
pub fn tmp_beside(path: &Path) -> PathBuf {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".stature-tmp");
    PathBuf::from(tmp)
}

/// A temporary file beside `target` that only this process writes: open,
/// emptied, and holding an exclusive `flock` until it is closed (after
/// the rename). `PATH.stature-tmp`, or `PATH.stature-tmp.PID` while
/// another process holds that one: two processes replacing one file (a
/// service and an installer's `stature snapshot` with its config) would
/// otherwise write into one temporary file, and the second would go on
/// writing into the first one's file after its rename put it in place.
/// Each now renames a complete file of its own; the last one stays. On a
/// file system without locks it is `PATH.stature-tmp`, unlocked, as before.
pub fn create_own_tmp(target: &Path) -> io::Result<(PathBuf, std::fs::File)> {
    let shared = tmp_beside(target);
    let first = match open_locked(&shared) {
        Ok(Some(file)) => {
            remove_abandoned(&shared);
            return Ok((shared, file));
        }
        Ok(None) => None,
        // Something left at the name that this process cannot use (a
        // FIFO, another user's file): a name of its own will do as well.
        Err(e) => Some(e),
    };
    let mut own = shared.clone().into_os_string();
    own.push(format!(".{}", std::process::id()));
    let own = PathBuf::from(own);
    match open_locked(&own) {
        Ok(Some(file)) => {
            remove_abandoned(&shared);
            Ok((own, file))
        }
        Ok(None) => Err(io::Error::new(
            io::ErrorKind::WouldBlock,
            format!("{} is in use by another process", own.display()),
        )),
        // Both failed (an unwritable directory): the shared name's reason.
        Err(e) => Err(first.unwrap_or(e)),
    }
}

/// Removes the `SHARED.PID` files beside `shared` that no process holds:
/// left by a second writer killed before its rename, they would otherwise
/// stay for good, as later writers take the shared name. A live writer
/// holds its file's lock, so its file is left alone (this process's own
/// too: a lock held through another open file is busy to this one); so
/// is a file this process may not open.
fn remove_abandoned(shared: &Path) {
    let Some(name) = shared.file_name() else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(dir_of(shared)) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name();
        let pid = file
            .as_encoded_bytes()
            .strip_prefix(name.as_encoded_bytes())
            .and_then(|rest| rest.strip_prefix(b"."));
        if !pid.is_some_and(|p| !p.is_empty() && p.iter().all(u8::is_ascii_digit)) {
            continue;
        }
        let path = entry.path();
        if let Ok(Locked::Held(fd)) = lock_at(&path, rustix::fs::OFlags::WRONLY) {
            // Removed while locked: a writer that opened it just now
            // finds it gone from the path once it gets the lock.
            let _ = std::fs::remove_file(&path);
            drop(fd);
        }
    }
}

/// Opens `path` for writing (created if missing) and takes its exclusive
/// lock without waiting; `None` when another process holds it. Emptied
/// only once locked, so another writer's content is never cut short.
fn open_locked(path: &Path) -> io::Result<Option<std::fs::File>> {
    let fd = match lock_at(path, rustix::fs::OFlags::WRONLY)? {
        Locked::Held(fd) | Locked::Unsupported(fd, _) => fd,
        Locked::Busy => return Ok(None),
    };
    rustix::fs::ftruncate(&fd, 0).map_err(|e| {
        let e = io::Error::from(e);
        io::Error::new(e.kind(), format!("cannot create {}: {e}", path.display()))
    })?;
    Ok(Some(std::fs::File::from(fd)))
}

/// What [`lock_at`] got.
pub(crate) enum Locked {
    /// The exclusive lock of the file now at the path, held while the
    /// descriptor is open.
    Held(rustix::fd::OwnedFd),
    /// Another process holds it.
    Busy,
    /// The file system cannot lock (NFS without lockd, some FUSE file
    /// systems): the file, unlocked, and why (for the log).
    Unsupported(rustix::fd::OwnedFd, io::Error),
}

/// Opens (creating it when missing) the regular file `path` with `access`
/// (`RDONLY`: `flock` needs no write access) and tries its exclusive
/// `flock` once, without waiting. Non-blocking open: a FIFO put at the
/// path is refused instead of waited on. A holder that renamed or removed
/// the file between this open and this lock leaves a lock on a file no
/// longer at the path: then it opens again (a few times; a path whose
/// file keeps being replaced under it counts as busy).
pub(crate) fn lock_at(path: &Path, access: rustix::fs::OFlags) -> io::Result<Locked> {
    use rustix::fs::{flock, fstat, open, stat, FileType, FlockOperation, Mode, OFlags};
    let not_regular = || {
        format!(
            "cannot create {}: something not a regular file is there",
            path.display()
        )
    };
    let named = |e: rustix::io::Errno| {
        let e = io::Error::from(e);
        // A FIFO with no reader fails the open itself (ENXIO): say what
        // is in the way rather than the errno's words.
        if std::fs::symlink_metadata(path).is_ok_and(|m| !m.is_file()) {
            return io::Error::new(e.kind(), not_regular());
        }
        let e = name_missing_dir(path, e);
        io::Error::new(e.kind(), format!("cannot create {}: {e}", path.display()))
    };
    for _ in 0..4 {
        let fd = open(
            path,
            access | OFlags::CREATE | OFlags::CLOEXEC | OFlags::NONBLOCK,
            Mode::from_raw_mode(0o644),
        )
        .map_err(named)?;
        let meta = fstat(&fd).map_err(named)?;
        if FileType::from_raw_mode(meta.st_mode) != FileType::RegularFile {
            return Err(io::Error::other(not_regular()));
        }
        match flock(&fd, FlockOperation::NonBlockingLockExclusive) {
            Ok(()) => {
                let here =
                    stat(path).is_ok_and(|b| b.st_dev == meta.st_dev && b.st_ino == meta.st_ino);
                if here {
                    return Ok(Locked::Held(fd));
                }
            }
            Err(rustix::io::Errno::WOULDBLOCK) => return Ok(Locked::Busy),
            Err(e) => {
                let e = io::Error::from(e);
                let why = io::Error::new(e.kind(), format!("cannot lock {}: {e}", path.display()));
                return Ok(Locked::Unsupported(fd, why));
            }
        }
    }
    Ok(Locked::Busy)
}

/// Checks now, before any work whose result goes to `path`, that the file
/// can be replaced later: [`target`] is resolved and a temporary file of
/// this process's own ([`create_own_tmp`]) is created and removed beside
/// it (a missing or read-only directory, a full inode table). Returns the
/// target. The error names the path that failed. A temporary file another
/// process is writing (a service's snapshot or state, another training's
/// weights) is neither emptied nor removed: that process's rename would
/// put a torn file in place, or fail.
pub fn probe(path: &Path) -> io::Result<PathBuf> {
    let target = target(path)?;
    if target.file_name().is_none() {
        return Err(io::Error::other("not a file name"));
    }
    let (tmp, file) = create_own_tmp(&target)?;
    // Removed while still locked, as every writer of these names does.
    let _ = std::fs::remove_file(&tmp);
    drop(file);
    Ok(target)
}

/// The new content of a file, written and synced to a temporary file of
/// this process's own beside it ([`create_own_tmp`]) but not yet in place:
/// [`Staged::commit`] renames it over the path. Staging every output of a
/// command first means a failure writing one leaves all of them as they
/// were. Dropped uncommitted, the temporary file is removed.
#[derive(Debug)]
pub struct Staged {
    path: PathBuf,
    tmp: PathBuf,
    /// The temporary file, open so that its lock lasts until the rename
    /// (or the removal): another writer of the path takes another name.
    file: Option<std::fs::File>,
    committed: bool,
}

impl Staged {
    /// Writes `bytes` beside `path` (through a symbolic link, like [`target`]).
    pub fn write(path: &Path, bytes: &[u8]) -> io::Result<Staged> {
        use std::io::Write;
        let path = target(path)?;
        let (tmp, file) = create_own_tmp(&path)?;
        let mut staged = Staged {
            tmp,
            path,
            file: Some(file),
            committed: false,
        };
        if let Some(f) = staged.file.as_mut() {
            f.write_all(bytes)?;
            f.sync_all()?;
        }
        Ok(staged)
    }

    /// Moves the new content into place.
    pub fn commit(mut self) -> io::Result<()> {
        std::fs::rename(&self.tmp, &self.path)?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        // Removed before the file (and its lock) is closed, so that no
        // other writer takes the name up in between.
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
        drop(self.file.take());
    }
}

/// Why [`read_capped`] returned nothing.
#[derive(Debug)]
pub enum ReadError {
    /// Opening or reading failed.
    Io(io::Error),
    /// The file holds more than the cap (it was not read past it).
    TooLarge {
        /// The cap, bytes.
        cap: u64,
    },
}

impl core::fmt::Display for ReadError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ReadError::Io(e) => write!(f, "{e}"),
            ReadError::TooLarge { cap } if cap % (1 << 20) == 0 => {
                write!(f, "larger than {} MiB", cap >> 20)
            }
            ReadError::TooLarge { cap } if cap % (1 << 10) == 0 => {
                write!(f, "larger than {} KiB", cap >> 10)
            }
            ReadError::TooLarge { cap } => write!(f, "larger than {cap} bytes"),
        }
    }
}

/// Reads a whole file the product bounds in size (state, config, weights):
/// at most `cap` bytes, so a mistyped path naming a video, a device such
/// as `/dev/zero` or a huge file costs one read of `cap + 1` bytes instead
/// of all the memory there is.
pub fn read_capped(path: &Path, cap: u64) -> Result<Vec<u8>, ReadError> {
    let f = std::fs::File::open(path).map_err(ReadError::Io)?;
    read_capped_from(f, cap)
}

/// [`read_capped`] of a file already open (checked after the open, so
/// that what is read is what was checked).
pub fn read_capped_from(f: std::fs::File, cap: u64) -> Result<Vec<u8>, ReadError> {
    use std::io::Read;
    let mut bytes = Vec::new();
    f.take(cap + 1)
        .read_to_end(&mut bytes)
        .map_err(ReadError::Io)?;
    if bytes.len() as u64 > cap {
        return Err(ReadError::TooLarge { cap });
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> crate::scratch::ScratchDir {
        crate::scratch::fresh_dir(&format!("replace-{name}"))
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

    #[test]
    fn staged_content_replaces_the_file_only_when_committed() {
        let d = scratch("staged");
        let f = d.join("w.bin");
        std::fs::write(&f, b"old").unwrap();
        drop(Staged::write(&f, b"new").unwrap());
        assert_eq!(std::fs::read(&f).unwrap(), b"old");
        assert!(
            !tmp_beside(&f).exists(),
            "an uncommitted stage leaves no file"
        );
        Staged::write(&f, b"new").unwrap().commit().unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"new");
        assert!(!tmp_beside(&f).exists());
    }

    #[test]
    fn two_writers_of_one_path_each_commit_a_whole_file() {
        let d = scratch("staged-two");
        let f = d.join("w.bin");
        let first = Staged::write(&f, &[1u8; 4096]).unwrap();
        // Another training's start-up check, then its write, meanwhile
        // (one process here: the second name is this PID's).
        assert_eq!(probe(&f).unwrap(), f);
        let second = Staged::write(&f, &[2u8; 100]).unwrap();
        first.commit().unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), [1u8; 4096]);
        second.commit().unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), [2u8; 100]);
        let left: Vec<_> = std::fs::read_dir(&*d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n != "w.bin")
            .collect();
        assert!(left.is_empty(), "temporary files left: {left:?}");
    }

    #[test]
    fn probe_names_the_file_it_could_not_create() {
        let d = scratch("probe");
        assert_eq!(probe(&d.join("a")).unwrap(), d.join("a"));
        assert!(!tmp_beside(&d.join("a")).exists());
        let e = probe(&d.join("missing/a")).unwrap_err();
        assert!(e.to_string().contains("missing/a.stature-tmp"), "{e}");
    }

    #[test]
    fn capped_reads_stop_past_the_cap() {
        let d = scratch("capped");
        let f = d.join("c");
        std::fs::write(&f, [7u8; 100]).unwrap();
        assert_eq!(read_capped(&f, 100).unwrap().len(), 100);
        let e = read_capped(&f, 99).unwrap_err();
        assert!(matches!(e, ReadError::TooLarge { cap: 99 }), "{e}");
        assert_eq!(e.to_string(), "larger than 99 bytes");
        #[cfg(unix)]
        assert_eq!(
            read_capped(Path::new("/dev/zero"), 1 << 20)
                .unwrap_err()
                .to_string(),
            "larger than 1 MiB"
        );
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
