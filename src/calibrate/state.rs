//! The calibration state file: the anchor store of the calibrator as JSON,
//! written atomically (temporary file in the same directory, `fsync`,
//! rename, then `fsync` of the directory) so that a power cut leaves either
//! the old or the new file, never a torn one. A state file that cannot be
//! parsed, or that is for another frame size, is reported and renamed
//! aside ([`StateFile::set_aside`]): calibration starts afresh. One that
//! cannot be read (permissions, a failing card) is left where it is and
//! the run keeps no state.
//!
//! Writing serialises into a buffer allocated once, so the periodic writes
//! the loop makes do not allocate (paths shorter than a few hundred bytes
//! are converted on the stack by `std`).
//!
//! One process writes a state file at a time. Two writers would share the
//! temporary file `PATH.stature-tmp`: one renames it into place while the
//! other is still writing into the same inode, and readers see a torn
//! file (an installer's `stature snapshot` with the service's config,
//! while the service runs). So [`StateFile::open`] takes an exclusive
//! advisory lock (`flock`) on `PATH.stature-lock` beside the state file and
//! holds it as long as the `StateFile` lives; a process that finds it
//! taken resumes from the state but never writes or moves it
//! ([`StateFile::in_use_elsewhere`]). The lock is on a file of its own
//! because every write replaces the state file's inode, and with it any
//! lock on it.

use super::geometry::Anchor;
use super::Slot;
use serde::ser::{SerializeSeq, SerializeStruct};
use serde::{Deserialize, Serialize, Serializer};
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Format version written in the file.
pub const STATE_VERSION: u32 = 1;

/// The largest file read as a state file. An anchor is about 135 bytes of
/// JSON (under 200 with every number at full length), so the largest store
/// a configuration may keep ([`super::MAX_ANCHORS`], 8,192 anchors) is
/// under 1.7 MB: the cap leaves ample room and still refuses a video.
pub const MAX_STATE_BYTES: u64 = 16 << 20;

/// Why a process that does not hold the lock leaves the state alone.
pub const IN_USE: &str = "in use by another stature process";

/// A loaded state file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Saved {
    /// Format version.
    pub version: u32,
    /// Frame width the anchors refer to.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Anchors per track, oldest first (files of earlier builds have no
    /// `motion`: those anchors count as standing).
    pub tracks: Vec<Vec<Anchor>>,
}

/// Borrowed view of the store, serialised without copying.
pub(super) struct StateView<'a> {
    pub width: u32,
    pub height: u32,
    pub tracks: &'a [Slot],
    pub anchors: &'a [Anchor],
    pub per_track: usize,
}

struct Tracks<'a>(&'a StateView<'a>);

impl Serialize for Tracks<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let v = self.0;
        let mut seq = s.serialize_seq(None)?;
        for (i, t) in v.tracks.iter().enumerate() {
            if t.used && t.len > 0 {
                let base = i * v.per_track;
                seq.serialize_element(&v.anchors[base..base + t.len])?;
            }
        }
        seq.end()
    }
}

impl Serialize for StateView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut st = s.serialize_struct("Saved", 4)?;
        st.serialize_field("version", &STATE_VERSION)?;
        st.serialize_field("width", &self.width)?;
        st.serialize_field("height", &self.height)?;
        st.serialize_field("tracks", &Tracks(self))?;
        st.end()
    }
}

/// Why a state file could not be used.
#[derive(Debug)]
pub enum StateError {
    /// Reading or writing failed.
    Io(std::io::Error),
    /// The content is not a state file of this version.
    Corrupt(String),
}

impl core::fmt::Display for StateError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StateError::Io(e) => write!(f, "{e}"),
            StateError::Corrupt(m) => write!(f, "corrupt state file: {m}"),
        }
    }
}

/// A state file with its write buffer.
#[derive(Debug)]
pub struct StateFile {
    path: PathBuf,
    tmp: PathBuf,
    /// `PATH.stature-lock`, kept: a reader retries it at every write
    /// ([`StateFile::take_over`]), which must not allocate.
    lock_path: PathBuf,
    dir: PathBuf,
    buf: Vec<u8>,
    lock: Lock,
}

/// Whether this process may write the state file.
#[derive(Debug)]
enum Lock {
    /// Not asked for ([`StateFile::new`]), or the file system cannot lock
    /// (the error, for the log): writes go ahead as they did before locks.
    None(Option<std::io::Error>),
    /// This process holds the lock on this open file: it writes the state.
    /// Never read: closing the file (dropping the `StateFile`) releases it.
    Held(#[allow(dead_code)] rustix::fd::OwnedFd),
    /// Another process holds it: the state is read, never written.
    Busy,
}

/// `PATH.stature-lock`: the lock file beside `path`.
pub fn lock_beside(path: &Path) -> PathBuf {
    let mut lock = path.as_os_str().to_owned();
    lock.push(".stature-lock");
    PathBuf::from(lock)
}

/// Attempts at the lock before a process leaves the state to its holder,
/// [`LOCK_RETRY`] apart: a `config --check` holds it for the moment it
/// takes to create and remove the temporary file, and must not turn a
/// service starting just then into a reader for its whole run. (A run
/// holds it from its start-up check to its end: the checked file is
/// handed to the loop, not opened twice.)
const LOCK_TRIES: u32 = 10;
/// Time between attempts at the lock.
const LOCK_RETRY: std::time::Duration = std::time::Duration::from_millis(20);

/// Opens (creating it when missing) the lock file `path` and takes its
/// exclusive lock, without waiting more than [`LOCK_TRIES`] attempts.
/// Opened read-only: `flock` needs no write access, and a lock file an
/// installer created as root must still be usable by the service's user.
fn take_lock(path: &Path) -> std::io::Result<Lock> {
    use crate::replace::{lock_at, Locked};
    for _ in 0..LOCK_TRIES {
        match lock_at(path, rustix::fs::OFlags::RDONLY)? {
            Locked::Held(fd) => return Ok(Lock::Held(fd)),
            Locked::Busy => std::thread::sleep(LOCK_RETRY),
            // One process alone still works as it always did.
            Locked::Unsupported(_, e) => return Ok(Lock::None(Some(e))),
        }
    }
    Ok(Lock::Busy)
}

impl Drop for StateFile {
    /// The holder removes the lock file while it still holds the lock, so
    /// a check (`config --check`) leaves nothing behind. Safe because a
    /// process that then gets the lock of the removed file sees that it is
    /// no longer at the path and takes the lock of the path's new file.
    fn drop(&mut self) {
        if matches!(self.lock, Lock::Held(_)) {
            let _ = std::fs::remove_file(lock_beside(&self.path));
        }
    }
}

/// Parses the bytes of a state file (the fuzzed entry point of [`StateFile::load`]).
pub fn parse_state(bytes: &[u8]) -> Result<Saved, StateError> {
    let saved: Saved =
        serde_json::from_slice(bytes).map_err(|e| StateError::Corrupt(e.to_string()))?;
    if saved.version != STATE_VERSION {
        return Err(StateError::Corrupt(format!(
            "version {} (expected {STATE_VERSION})",
            saved.version
        )));
    }
    Ok(saved)
}

impl StateFile {
    /// A state file at `path`; `capacity` bytes of serialisation buffer.
    /// Nothing is checked: [`StateFile::open`] is what a run uses.
    pub fn new(path: &Path, capacity: usize) -> Self {
        StateFile {
            path: path.to_path_buf(),
            tmp: crate::replace::tmp_beside(path),
            lock_path: lock_beside(path),
            dir: crate::replace::dir_of(path).to_path_buf(),
            buf: Vec::with_capacity(capacity),
            lock: Lock::None(None),
        }
    }

    /// A state file at `path`, checked now so that a run does not find out
    /// at its first write: a symbolic link is followed (the file it points
    /// to is the one replaced), anything but a regular file is refused, the
    /// lock `PATH.stature-lock` is taken (see the module's text) and, when
    /// this process got it, `PATH.stature-tmp` is created and removed in
    /// the target's directory. When another process holds the lock the
    /// temporary file is not touched (it may be that process's write in
    /// progress) and the result only reads ([`StateFile::in_use_elsewhere`]).
    /// The lock lasts as long as the result: a check that drops it at once
    /// (`config --check`) leaves the state to the run that comes next.
    pub fn open(path: &Path, capacity: usize) -> Result<Self, StateError> {
        let target = crate::replace::target(path).map_err(StateError::Io)?;
        if target.file_name().is_none() {
            return Err(StateError::Io(std::io::Error::other("not a file name")));
        }
        let mut file = StateFile::new(&target, capacity);
        // Taken before the probe: the probe's temporary file is the
        // holder's, and dropping `file` on an error removes the lock file.
        file.lock = take_lock(&file.lock_path).map_err(StateError::Io)?;
        if !file.in_use_elsewhere() {
            crate::replace::probe(&target).map_err(StateError::Io)?;
        }
        Ok(file)
    }

    /// A reader tries the lock once more (without waiting), so that a run
    /// that started while another held the state (a service restarted
    /// during an installer's `stature snapshot`) writes it once that one
    /// is gone, instead of never. Its calibration then replaces what the
    /// other wrote after this run resumed. Returns whether it now writes.
    fn take_over(&mut self) -> bool {
        use crate::replace::{lock_at, Locked};
        match lock_at(&self.lock_path, rustix::fs::OFlags::RDONLY) {
            Ok(Locked::Held(fd)) => {
                self.lock = Lock::Held(fd);
                log::info!(
                    "calibration state {}: the other stature process let it go; this run writes it from now on",
                    self.path.display()
                );
                true
            }
            _ => false,
        }
    }

    /// Another stature process holds the state's lock: this one may read
    /// the state but [`StateFile::write`] and [`StateFile::set_aside`]
    /// leave it alone.
    pub fn in_use_elsewhere(&self) -> bool {
        matches!(self.lock, Lock::Busy)
    }

    /// Why the state could not be locked, when the file system does not
    /// support locks (the state is then written unlocked, as by one
    /// process alone).
    pub fn lock_error(&self) -> Option<&std::io::Error> {
        match &self.lock {
            Lock::None(e) => e.as_ref(),
            _ => None,
        }
    }

    /// Moves a file that cannot be resumed from out of the way, so that the
    /// run's first write does not destroy it (a mistyped `--state` may name
    /// someone's config or video; a state of another frame size is still
    /// good for that size): renamed to `PATH.SUFFIX`, or `PATH.SUFFIX.N`
    /// (N = 1..=99) when that exists. Returns the new path.
    ///
    /// Refused when another process holds the lock: the file is that
    /// process's to keep or move.
    pub fn set_aside(&self, suffix: &str) -> std::io::Result<PathBuf> {
        if self.in_use_elsewhere() {
            return Err(std::io::Error::other(IN_USE));
        }
        for n in 0..100 {
            let mut aside = self.path.as_os_str().to_owned();
            aside.push(".");
            aside.push(suffix);
            if n > 0 {
                aside.push(format!(".{n}"));
            }
            let aside = PathBuf::from(aside);
            use rustix::fs::{renameat_with, RenameFlags, CWD};
            match renameat_with(CWD, &self.path, CWD, &aside, RenameFlags::NOREPLACE) {
                Ok(()) => return Ok(aside),
                Err(rustix::io::Errno::EXIST) => continue,
                // A file system without RENAME_NOREPLACE: look, then rename.
                Err(rustix::io::Errno::INVAL | rustix::io::Errno::NOSYS) => {
                    if std::fs::symlink_metadata(&aside).is_err() {
                        std::fs::rename(&self.path, &aside)?;
                        return Ok(aside);
                    }
                }
                Err(e) => return Err(e.into()),
            }
        }
        Err(std::io::Error::other(format!(
            "{}.{suffix} .. .{suffix}.99 all exist",
            self.path.display()
        )))
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Reads the file: `Ok(None)` when it does not exist. A file larger
    /// than any state file ([`MAX_STATE_BYTES`]) is not read at all: a
    /// mistyped path may name a video.
    pub fn load(&self) -> Result<Option<Saved>, StateError> {
        use crate::replace::{read_capped, ReadError};
        let text = match read_capped(&self.path, MAX_STATE_BYTES) {
            Ok(t) => t,
            Err(ReadError::Io(e)) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(ReadError::Io(e)) => return Err(StateError::Io(e)),
            Err(e @ ReadError::TooLarge { .. }) => {
                return Err(StateError::Corrupt(format!(
                    "{e}, too large to be a state file"
                )))
            }
        };
        parse_state(&text).map(Some)
    }

    /// Writes atomically: temp file, fsync, rename, fsync of the directory.
    /// Does nothing when another process holds the lock.
    pub(super) fn write(&mut self, view: &StateView<'_>) -> Result<(), StateError> {
        if self.in_use_elsewhere() && !self.take_over() {
            return Ok(());
        }
        self.buf.clear();
        serde_json::to_writer(&mut self.buf, view)
            .map_err(|e| StateError::Corrupt(e.to_string()))?;
        self.buf.push(b'\n');
        let written = File::create(&self.tmp).and_then(|mut f| {
            f.write_all(&self.buf)?;
            f.sync_all()
        });
        if let Err(e) = written.and_then(|()| std::fs::rename(&self.tmp, &self.path)) {
            // A full disk: the torn temporary file would hold on to the
            // space the next write needs.
            let _ = std::fs::remove_file(&self.tmp);
            return Err(StateError::Io(e));
        }
        // The rename itself is durable only once the directory is synced;
        // some filesystems refuse to open directories, which is harmless.
        if let Ok(d) = File::open(&self.dir) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}
