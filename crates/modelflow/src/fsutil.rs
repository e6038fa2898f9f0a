//! Safe file output: everything the library writes goes to a temporary name in the destination
//! folder and is renamed into place, so a crash or an error never leaves a half-written file and
//! never destroys the previous version.

use crate::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// The temporary name `path` is written under before the rename (`.NAME.PID.tmp` in its folder,
/// which is made if missing).
fn temporary_beside(path: &Path) -> Result<std::path::PathBuf> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let name = path
        .file_name()
        .ok_or_else(|| Error::option("path", path.display(), "a file path"))?;
    Ok(dir.join(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Like [`write_atomic`], with the content produced by a writer callback.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = temporary_beside(path)?;
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(file);
        fill(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}

/// Writes two files that belong together (a point cache and the mesh beside it) so that either
/// both are replaced or neither: each goes to a temporary name first, and only when both are
/// written are they renamed into place. On an error the temporaries are removed and the old
/// files are left as they were.
pub fn write_atomic_pair(first: (&Path, &[u8]), second: (&Path, &[u8])) -> Result<()> {
    let tmp_of = |path: &Path| -> Result<std::path::PathBuf> {
        if let Some(kind) = not_a_file(path) {
            return Err(Error::invalid(
                path,
                "output",
                format!("is {kind}, not a file"),
            ));
        }
        temporary_beside(path)
    };
    let write = |tmp: &Path, bytes: &[u8]| -> std::io::Result<()> {
        let mut f = std::fs::File::create(tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    };
    let (t1, t2) = (tmp_of(first.0)?, tmp_of(second.0)?);
    let written = write(&t1, first.1)
        .map_err(|e| Error::io(first.0, e))
        .and_then(|()| write(&t2, second.1).map_err(|e| Error::io(second.0, e)));
    let renamed = written.and_then(|()| {
        std::fs::rename(&t1, first.0).map_err(|e| Error::io(first.0, e))?;
        std::fs::rename(&t2, second.0).map_err(|e| Error::io(second.0, e))
    });
    if renamed.is_err() {
        let _ = std::fs::remove_file(&t1);
        let _ = std::fs::remove_file(&t2);
    }
    renamed
}

/// Whether two paths name the same file (compared as given when either cannot be resolved).
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// What `path` is when it exists but is not a regular file (`"a folder"`, `"a FIFO"`, ...), so
/// that readers refuse it with a reason instead of "not found" or a read that never ends.
pub fn not_a_file(path: &Path) -> Option<&'static str> {
    let meta = std::fs::metadata(path).ok()?;
    if meta.is_file() {
        return None;
    }
    if meta.is_dir() {
        return Some("a folder");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if t.is_char_device() || t.is_block_device() {
            return Some("a device");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a regular file")
}

/// Refuses a path that exists but is not a regular file, naming what it is.
pub fn require_file(path: &Path, what: &str) -> Result<()> {
    match not_a_file(path) {
        Some(kind) => Err(Error::invalid(
            path,
            what,
            format!("is {kind}, not a regular file"),
        )),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write_atomic(&p, b"old").unwrap();
        let err = write_atomic_with(&p, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("disk full"))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "no temporary file is left behind");
    }
}
