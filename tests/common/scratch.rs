//! Scratch directories and file-system fixtures for tests, shared by the
//! integration tests (`tests/common`) and the library's unit tests
//! (`#[path]` in `lib.rs`).

/// An empty scratch directory `stature-<name>-<pid>` under the system temp
/// dir (emptied first if an earlier run left it), removed when dropped —
/// except while a test is failing, so that what it wrote can be read.
pub fn fresh_dir(name: &str) -> ScratchDir {
    let dir = std::env::temp_dir().join(format!("stature-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    ScratchDir(dir)
}

/// A test's scratch directory (see [`fresh_dir`]); derefs to its path.
#[derive(Debug)]
pub struct ScratchDir(std::path::PathBuf);

impl std::ops::Deref for ScratchDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::path::Path> for ScratchDir {
    fn as_ref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept for inspection: {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// Makes a FIFO at `path` (mode 0600): the file type that blocks an
/// `open(2)` until the other end opens, which every path the product opens
/// must survive.
pub fn mkfifo(path: &std::path::Path) {
    rustix::fs::mknodat(
        rustix::fs::CWD,
        path,
        rustix::fs::FileType::Fifo,
        rustix::fs::Mode::from_raw_mode(0o600),
        0,
    )
    .unwrap();
}
