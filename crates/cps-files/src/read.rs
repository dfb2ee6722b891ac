//! Bounded reading: a file is read only if it is a regular file, and only up to a
//! ceiling, checked before a byte is read (and again while reading, for a file that grows).

use std::fs::{File, Metadata};
use std::io::Read;
use std::path::Path;

use crate::FileError;

/// The largest configuration file read (experiments, scenes, robots, models): 16 MiB.
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// What a path is, in words, when it is not a regular file.
fn kind_of(meta: &Metadata) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_file() {
        None
    } else if t.is_dir() {
        Some("a folder")
    } else if t.is_fifo() {
        Some("a FIFO (a named pipe)")
    } else if t.is_char_device() || t.is_block_device() {
        Some("a device")
    } else if t.is_socket() {
        Some("a socket")
    } else {
        Some("not a file")
    }
}

/// Checks that `path` is a regular file of at most `ceiling` bytes and opens it; the
/// returned size is the file's when it was opened. For readers that need a `File` (a
/// parquet reader); they must not read past the size.
pub fn open(path: &Path, ceiling: u64, what: &str) -> Result<(File, u64), FileError> {
    let unreadable = |source| FileError::Unreadable {
        path: path.to_path_buf(),
        what: what.to_string(),
        source,
    };
    // Asked before opening: opening a FIFO for reading waits for a writer.
    let meta = std::fs::metadata(path).map_err(unreadable)?;
    regular(path, &meta, ceiling, what)?;
    let file = File::open(path).map_err(unreadable)?;
    // Asked again of what was opened, which a rename in between may have changed.
    let meta = file.metadata().map_err(unreadable)?;
    regular(path, &meta, ceiling, what)?;
    Ok((file, meta.len()))
}

fn regular(path: &Path, meta: &Metadata, ceiling: u64, what: &str) -> Result<(), FileError> {
    if let Some(kind) = kind_of(meta) {
        return Err(FileError::NotRegular {
            path: path.to_path_buf(),
            what: what.to_string(),
            kind,
        });
    }
    if meta.len() > ceiling {
        return Err(FileError::TooLarge {
            path: path.to_path_buf(),
            what: what.to_string(),
            size: meta.len(),
            ceiling,
            hint: "; is it the right file?".into(),
        });
    }
    Ok(())
}

/// At most `n` bytes of an opened file, into a buffer of `capacity`.
fn up_to(file: File, n: u64, capacity: u64, path: &Path, what: &str) -> Result<Vec<u8>, FileError> {
    let mut bytes = Vec::with_capacity(capacity.min(n) as usize);
    file.take(n)
        .read_to_end(&mut bytes)
        .map_err(|source| FileError::Unreadable {
            path: path.to_path_buf(),
            what: what.to_string(),
            source,
        })?;
    Ok(bytes)
}

/// Reads a whole regular file of at most `ceiling` bytes.
pub fn read_bytes(path: &Path, ceiling: u64, what: &str) -> Result<Vec<u8>, FileError> {
    let (file, size) = open(path, ceiling, what)?;
    let bytes = up_to(file, ceiling + 1, size, path, what)?;
    if bytes.len() as u64 > ceiling {
        return Err(FileError::TooLarge {
            path: path.to_path_buf(),
            what: what.to_string(),
            size: bytes.len() as u64,
            ceiling,
            hint: " (it grew while being read)".into(),
        });
    }
    Ok(bytes)
}

/// The first `n` bytes of a regular file (fewer when it is shorter), whatever its size:
/// for recognising a file by its head.
pub fn head(path: &Path, n: u64, what: &str) -> Result<Vec<u8>, FileError> {
    let (file, size) = open(path, u64::MAX, what)?;
    up_to(file, n, size, path, what)
}

/// Reads a whole regular file of at most `ceiling` bytes as UTF-8 text.
pub fn read_text(path: &Path, ceiling: u64, what: &str) -> Result<String, FileError> {
    let bytes = read_bytes(path, ceiling, what)?;
    String::from_utf8(bytes).map_err(|e| FileError::NotText {
        path: path.to_path_buf(),
        what: what.to_string(),
        offset: e.utf8_error().valid_up_to(),
    })
}

thread_local! {
    static GUARDED: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// Runs `read`, a dependency's reader of the file `path`, turning a panic inside it into
/// [`FileError::Malformed`] naming the file: no input makes cps panic, whatever the
/// library does with it. A front end's panic hook may stay quiet while [`guarded`] is
/// true (the sentence says it instead).
pub fn guard<T, E>(
    path: &Path,
    what: &str,
    read: impl FnOnce() -> Result<T, E>,
) -> Result<Result<T, E>, FileError> {
    GUARDED.with(|g| g.set(g.get() + 1));
    let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(read));
    GUARDED.with(|g| g.set(g.get() - 1));
    out.map_err(|panic| {
        let message = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "no message".into());
        let message: String = message.chars().take(200).collect();
        FileError::Malformed {
            path: path.to_path_buf(),
            what: what.to_string(),
            message,
        }
    })
}

/// Keeps the process's panic hook quiet for the panics [`guard`] turns into a sentence (a
/// front end calls it once at its start; every other panic prints as before).
pub fn quiet_guarded_panics() {
    let printed = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |p| {
        if !guarded() {
            printed(p)
        }
    }));
}

/// Whether this thread is inside [`guard`] (for a panic hook: the panic becomes a
/// sentence, so printing it would say it twice).
pub fn guarded() -> bool {
    GUARDED.with(|g| g.get() > 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fifo_a_device_and_a_folder_are_refused_before_opening() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        // mkfifo(1): no libc in this crate.
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            // Opening it for reading would wait for a writer forever.
            let e = read_text(&fifo, 1 << 20, "mesh").unwrap_err().to_string();
            assert!(
                e.contains("must be a regular file") && e.contains("FIFO"),
                "{e}"
            );
        }
        let e = read_bytes(Path::new("/dev/zero"), 1 << 20, "mesh")
            .unwrap_err()
            .to_string();
        assert!(e.contains("a device"), "{e}");
        let e = read_bytes(dir.path(), 1 << 20, "mesh")
            .unwrap_err()
            .to_string();
        assert!(e.contains("a folder"), "{e}");
    }

    #[test]
    fn a_panic_inside_a_reader_becomes_a_sentence_naming_the_file() {
        let hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let r: Result<Result<(), ()>, _> =
            guard(Path::new("frames.parquet"), "parquet file", || {
                assert!(guarded());
                let v: Vec<u8> = Vec::new();
                let _ = v[3];
                Ok(())
            });
        std::panic::set_hook(hook);
        let e = r.unwrap_err().to_string();
        assert!(
            e.starts_with("frames.parquet: the parquet file is malformed"),
            "{e}"
        );
        assert!(e.contains("index out of bounds"), "{e}");
        assert!(!guarded());
        assert_eq!(
            guard(Path::new("x"), "x", || Ok::<_, ()>(1)).unwrap(),
            Ok(1)
        );
    }

    #[test]
    fn a_file_over_its_ceiling_is_refused_with_its_size() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("big.stl");
        std::fs::write(&f, vec![b'x'; 2000]).unwrap();
        let e = read_bytes(&f, 1000, "mesh").unwrap_err().to_string();
        assert!(e.contains("2000 bytes") && e.contains("1 KiB"), "{e}");
        assert_eq!(read_bytes(&f, 2000, "mesh").unwrap().len(), 2000);
        std::fs::write(&f, [0xff, 0xfe]).unwrap();
        let e = read_text(&f, 10, "scene file").unwrap_err().to_string();
        assert!(e.contains("not UTF-8") && e.contains("offset 0"), "{e}");
        let e = read_text(&dir.path().join("none"), 10, "scene file")
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot read the scene file"), "{e}");
    }
}
