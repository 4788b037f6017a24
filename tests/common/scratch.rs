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

/// Runs `check` while a thread stands by to open the FIFO `fifo` for
/// writing and close it again, which ends an open(2) that waits for a
/// writer: a test of "a FIFO is refused without opening it" then fails
/// on its message instead of hanging when the open blocks again.
pub fn with_fifo_writer<T>(fifo: &std::path::Path, check: impl FnOnce() -> T) -> T {
    use std::sync::atomic::{AtomicBool, Ordering};
    let done = std::sync::Arc::new(AtomicBool::new(false));
    let writer = std::thread::spawn({
        let (fifo, done) = (fifo.to_path_buf(), done.clone());
        move || {
            use std::os::unix::fs::OpenOptionsExt;
            // A non-blocking open for writing fails (ENXIO) until a
            // reader waits in its open.
            while !done.load(Ordering::SeqCst) {
                let w = std::fs::OpenOptions::new()
                    .write(true)
                    .custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32)
                    .open(&fifo);
                if w.is_ok() {
                    return;
                }
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
        }
    });
    let out = check();
    done.store(true, Ordering::SeqCst);
    writer.join().unwrap();
    out
}

/// A test's run count from the environment variable `var` (a positive
/// integer), else `default`. The emulated ARM runs (`cross/test.sh`) turn
/// the longest sweeps down with these: there each run costs about 30 times
/// its native time, and what the target could change (its libm, its
/// 32-bit sizes) shows on the first few runs as on the last.
pub fn runs_from_env(var: &str, default: usize) -> usize {
    match std::env::var(var) {
        Err(_) => default,
        Ok(v) => match v.parse() {
            Ok(n) if n > 0 => n,
            _ => panic!("{var}={v:?}: a positive integer, please"),
        },
    }
}
