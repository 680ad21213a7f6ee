//! A lock per cache key that several processes, on one machine or several sharing a network
//! filesystem, respect: the lock file is created exclusively and names its owner (host and
//! pid); the owner touches it while it works; a second process waits until the file is gone
//! (and then finds the result in the cache instead of computing it again); a lock untouched
//! for longer than [`KeyLockParams::stale_after`] belongs to a process that died and is taken
//! over.

use std::fs::{self, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, SystemTime};

use crate::ArtifactError;

/// How a [`KeyLock`] waits and refreshes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyLockParams {
    /// How often the owner touches its lock file (default 30 s).
    pub refresh_every: Duration,
    /// A lock file untouched this long is stale and taken over (default 5 min).
    pub stale_after: Duration,
    /// How often a waiting process looks again (default 1 s).
    pub poll_every: Duration,
}

impl Default for KeyLockParams {
    fn default() -> Self {
        KeyLockParams {
            refresh_every: Duration::from_secs(30),
            stale_after: Duration::from_secs(300),
            poll_every: Duration::from_secs(1),
        }
    }
}

/// A held lock: its file exists while the value lives, touched by a background thread, and is
/// removed on drop.
#[derive(Debug)]
pub struct KeyLock {
    path: PathBuf,
    stop: Arc<AtomicBool>,
    heartbeat: Option<JoinHandle<()>>,
}

impl KeyLock {
    /// Takes the lock file `path` (e.g. `<cache file>.lock`), waiting while another live owner
    /// holds it; `on_wait` hears the owner's line (host and pid) once when waiting starts. A
    /// stale lock is removed and taken.
    ///
    /// # Errors
    /// [`ArtifactError::Io`] when the lock file cannot be created or read for another reason
    /// than another owner holding it.
    pub fn acquire(
        path: &Path,
        params: &KeyLockParams,
        mut on_wait: impl FnMut(&str),
    ) -> Result<KeyLock, ArtifactError> {
        let io = |source| ArtifactError::Io {
            path: path.to_path_buf(),
            source,
        };
        if let Some(dir) = path.parent()
            && !dir.as_os_str().is_empty()
        {
            fs::create_dir_all(dir).map_err(|source| ArtifactError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        let mut told = false;
        loop {
            match OpenOptions::new().write(true).create_new(true).open(path) {
                Ok(mut file) => {
                    let owner = format!("{} {}\n", host_name(), std::process::id());
                    file.write_all(owner.as_bytes()).map_err(io)?;
                    return Ok(KeyLock::held(path.to_path_buf(), params.refresh_every));
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let age = fs::metadata(path)
                        .and_then(|m| m.modified())
                        .ok()
                        .and_then(|t| SystemTime::now().duration_since(t).ok());
                    match age {
                        // Gone in between: try again at once.
                        None if !path.exists() => continue,
                        Some(age) if age > params.stale_after => {
                            let _ = fs::remove_file(path);
                            continue;
                        }
                        _ => {}
                    }
                    if !told {
                        let owner = fs::read_to_string(path).unwrap_or_default();
                        on_wait(owner.trim());
                        told = true;
                    }
                    std::thread::sleep(params.poll_every);
                }
                Err(e) => return Err(io(e)),
            }
        }
    }

    fn held(path: PathBuf, refresh_every: Duration) -> KeyLock {
        let stop = Arc::new(AtomicBool::new(false));
        let heartbeat = {
            let (path, stop) = (path.clone(), Arc::clone(&stop));
            std::thread::spawn(move || {
                let tick = Duration::from_millis(100).min(refresh_every);
                let mut since = Duration::ZERO;
                while !stop.load(Ordering::Relaxed) {
                    std::thread::sleep(tick);
                    since += tick;
                    if since >= refresh_every {
                        since = Duration::ZERO;
                        if let Ok(file) = OpenOptions::new().write(true).open(&path) {
                            let _ = file.set_modified(SystemTime::now());
                        }
                    }
                }
            })
        };
        KeyLock {
            path,
            stop,
            heartbeat: Some(heartbeat),
        }
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for KeyLock {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(heartbeat) = self.heartbeat.take() {
            let _ = heartbeat.join();
        }
        let _ = fs::remove_file(&self.path);
    }
}

/// This machine's host name (`/proc/sys/kernel/hostname`, else `$HOSTNAME`, else "unknown"):
/// how a lock, a receipt or a shard names where it was made.
pub fn host_name() -> String {
    fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .ok()
        .filter(|h| !h.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "unknown".into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;
    use std::time::Instant;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("key-lock-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn fast() -> KeyLockParams {
        KeyLockParams {
            refresh_every: Duration::from_millis(50),
            stale_after: Duration::from_secs(2),
            poll_every: Duration::from_millis(10),
        }
    }

    #[test]
    fn a_second_taker_waits_until_the_first_lets_go_and_the_file_goes_with_the_lock() {
        let dir = scratch("wait");
        let path = dir.join("entry.bin.lock");
        let order = Mutex::new(Vec::new());
        let first = KeyLock::acquire(&path, &fast(), |_| {}).unwrap();
        assert!(
            fs::read_to_string(&path)
                .unwrap()
                .contains(&std::process::id().to_string())
        );
        std::thread::scope(|scope| {
            scope.spawn(|| {
                let mut heard = String::new();
                let _second =
                    KeyLock::acquire(&path, &fast(), |owner| heard = owner.into()).unwrap();
                assert!(heard.contains(&std::process::id().to_string()), "{heard}");
                order.lock().unwrap().push("second");
            });
            std::thread::sleep(Duration::from_millis(300));
            order.lock().unwrap().push("first done");
            drop(first);
        });
        assert_eq!(*order.lock().unwrap(), ["first done", "second"]);
        assert!(!path.exists());
    }

    #[test]
    fn a_held_lock_is_kept_fresh_and_a_stale_one_is_taken_over() {
        let dir = scratch("stale");
        let path = dir.join("entry.bin.lock");
        let held = KeyLock::acquire(&path, &fast(), |_| {}).unwrap();
        let old = SystemTime::now() - Duration::from_secs(60);
        OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_modified(old)
            .unwrap();
        std::thread::sleep(Duration::from_millis(200));
        let touched = fs::metadata(&path).unwrap().modified().unwrap();
        assert!(
            touched > old + Duration::from_secs(50),
            "the owner refreshes its lock"
        );
        drop(held);
        // A lock left by a process that died: untouched for longer than `stale_after`.
        fs::write(&path, "elsewhere 1\n").unwrap();
        OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_modified(old)
            .unwrap();
        let start = Instant::now();
        let _taken =
            KeyLock::acquire(&path, &fast(), |_| panic!("a stale lock is not waited for")).unwrap();
        assert!(start.elapsed() < Duration::from_secs(1));
    }
}
