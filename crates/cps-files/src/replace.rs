//! The one writer of outputs that may replace an old one: written beside its place, the
//! old one moved aside, the new one moved in, then what cps made of the old one removed.
//!
//! - An output is never written or removed through a symbolic link: a link in the output's
//!   place is refused, and removing the old output removes its entries (`unlink` removes a
//!   link, never what it points to).
//! - Nothing is removed before the new output is complete and in place, and at every
//!   moment the place holds the old output or the new one (two renames within a folder).
//! - `--force` replaces only what cps would have written: a file of the kind cps writes, or
//!   a folder holding exactly the files cps writes there. Anything else is refused before
//!   any work, and checked again at the swap.
//!
//! ```
//! use cps_files::replace::{Output, Shape};
//! # let dir = tempfile::tempdir()?;
//! let path = dir.path().join("rec.csv");
//! let staged = Output::new(&path, "recording", Shape::file(|_| true), false).stage()?;
//! std::fs::write(staged.path(), "t,q1\n0,0.1\n")?;
//! staged.commit()?;
//! assert_eq!(std::fs::read_to_string(&path)?, "t,q1\n0,0.1\n");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fs;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::FileError;

/// What an output is, so that `--force` removes only what cps makes.
#[derive(Clone)]
pub enum Shape {
    /// One file; the function says whether an existing file is one cps writes (by its
    /// contents: a CSV with cps's header, JSON of cps's format).
    File(Arc<dyn Fn(&Path) -> bool + Send + Sync>),
    /// A folder holding these files (relative, `/`-separated) and their folders, and
    /// nothing else; the first (its description) at least.
    Folder(Vec<String>),
}

impl Shape {
    /// A file, recognised as cps's by `ours`.
    pub fn file(ours: impl Fn(&Path) -> bool + Send + Sync + 'static) -> Self {
        Self::File(Arc::new(ours))
    }

    /// A folder of exactly these files.
    pub fn folder(files: &[&str]) -> Self {
        Self::Folder(files.iter().map(|f| f.to_string()).collect())
    }
}

/// An output to write: its place, what it is called in messages, its shape and whether
/// an old one may be replaced.
#[derive(Clone)]
pub struct Output {
    path: PathBuf,
    what: String,
    shape: Shape,
    force: bool,
}

/// An output being written: [`Staged::path`] is where to write it; [`Staged::commit`]
/// puts it in place. Dropped without a commit, it removes what it staged.
pub struct Staged {
    output: Output,
    staging: PathBuf,
    done: bool,
}

fn name_of(path: &Path) -> String {
    path.file_name()
        .map_or("output".into(), |n| n.to_string_lossy().into_owned())
}

/// A fresh name beside `path` (`.name.cps-<tag>-<pid>-<n>`), made as an empty file or
/// folder so no one else takes it.
fn fresh_beside(path: &Path, tag: &str, folder: bool) -> std::io::Result<PathBuf> {
    let name = name_of(path);
    for n in 0..1000 {
        let p = path.with_file_name(format!(".{name}.cps-{tag}-{}-{n}", std::process::id()));
        let made = if folder {
            fs::create_dir(&p)
        } else {
            fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&p)
                .map(drop)
        };
        match made {
            Ok(()) => return Ok(p),
            Err(e) if e.kind() == ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("no free name beside it"))
}

/// A name beside `path` nothing holds (for moving the old output aside).
fn free_beside(path: &Path, tag: &str) -> PathBuf {
    let name = name_of(path);
    (0..)
        .map(|n| path.with_file_name(format!(".{name}.cps-{tag}-{}-{n}", std::process::id())))
        .find(|p| fs::symlink_metadata(p).is_err())
        .expect("an unbounded range")
}

/// The first file (or link) under a folder, looking a few levels down.
fn first_file(dir: &Path) -> Option<PathBuf> {
    let mut stack = vec![(dir.to_path_buf(), 0)];
    while let Some((d, depth)) = stack.pop() {
        for entry in fs::read_dir(&d).ok()?.flatten() {
            match entry.file_type() {
                Ok(t) if t.is_dir() && depth < 8 => stack.push((entry.path(), depth + 1)),
                Ok(t) if t.is_dir() => {}
                _ => return Some(entry.path()),
            }
        }
    }
    None
}

impl Output {
    /// An output at `path`, called `what` in messages ("recording", "LeRobot dataset").
    pub fn new(path: &Path, what: &str, shape: Shape, force: bool) -> Self {
        Self {
            path: path.to_path_buf(),
            what: what.to_string(),
            shape,
            force,
        }
    }

    fn fail(&self, message: String) -> FileError {
        FileError::output(&self.path, message)
    }

    /// What in the folder is not one of the files cps writes there (or their folders),
    /// if anything: a path and what it is.
    fn foreign_in(&self, root: &Path, files: &[String]) -> Option<String> {
        let mut stack = vec![root.to_path_buf()];
        while let Some(dir) = stack.pop() {
            let Ok(entries) = fs::read_dir(&dir) else {
                return Some(format!("{} (unreadable)", dir.display()));
            };
            for entry in entries.flatten() {
                let path = entry.path();
                let rel = path
                    .strip_prefix(root)
                    .map(|r| r.to_string_lossy().replace('\\', "/"))
                    .unwrap_or_default();
                let Ok(t) = entry.file_type() else {
                    return Some(rel);
                };
                let is_file = files.contains(&rel);
                let is_dir = files.iter().any(|f| f.starts_with(&format!("{rel}/")));
                if t.is_dir() && is_dir {
                    stack.push(path);
                } else if t.is_dir() {
                    return Some(match first_file(&path) {
                        Some(f) => format!(
                            "{}, which cps did not write",
                            f.strip_prefix(root).unwrap_or(&f).display()
                        ),
                        None => format!("{rel} (a folder cps does not write there)"),
                    });
                } else if !(t.is_file() && is_file) {
                    let kind = if t.is_symlink() {
                        "a symbolic link"
                    } else if t.is_dir() {
                        "a folder"
                    } else {
                        "a file"
                    };
                    return Some(format!("{rel} ({kind} cps does not write there)"));
                }
            }
        }
        None
    }

    /// Checks, before any work, that the output may be written: its place is free, or
    /// holds an output of the same kind cps wrote and `force` is given. Never through a
    /// symbolic link.
    pub fn check(&self) -> Result<(), FileError> {
        let meta = match fs::symlink_metadata(&self.path) {
            Err(e) if e.kind() == ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(self.fail(format!("cannot be inspected ({e})"))),
            Ok(m) => m,
        };
        let what = &self.what;
        if meta.file_type().is_symlink() {
            let to = fs::read_link(&self.path)
                .map(|t| format!(" (to {})", t.display()))
                .unwrap_or_default();
            return Err(self.fail(format!(
                "is a symbolic link{to}; cps never writes or removes through a link: remove the link, or choose another place for the {what}"
            )));
        }
        let foreign = match &self.shape {
            Shape::File(_) if meta.is_dir() => Some("is a directory; give a file name".into()),
            Shape::File(_) if !meta.is_file() => {
                Some(format!("is not a file, and the {what} is one"))
            }
            Shape::File(_) if !self.force => {
                return Err(self.fail(
                    "already exists; pass --force to replace it or choose another name".into(),
                ));
            }
            Shape::File(ours) => (!ours(&self.path)).then(|| {
                "exists and does not look like a file cps writes there, so --force leaves it alone (choose another name)".to_string()
            }),
            Shape::Folder(files) => {
                if !meta.is_dir() {
                    Some(format!("exists and is not a folder, and the {what} is one"))
                } else if let Some(first) = files.first()
                    && !fs::symlink_metadata(self.path.join(first)).is_ok_and(|m| m.is_file())
                {
                    Some(format!(
                        "exists already, and is not a {what} cps would replace (it has no {first}), so cps leaves it alone; choose another place"
                    ))
                } else {
                    self.foreign_in(&self.path, files).map(|f| {
                        format!(
                            "exists already, and is not a {what} cps would replace (it holds {f}), so cps leaves it alone; choose another place"
                        )
                    })
                }
            }
        };
        match foreign {
            Some(why) => Err(self.fail(why)),
            None if !self.force => Err(self.fail(format!(
                "exists already (a {what} cps wrote: --force replaces it)"
            ))),
            None => Ok(()),
        }
    }

    /// Checks the output ([`Output::check`]) and makes its staging place beside it.
    pub fn stage(self) -> Result<Staged, FileError> {
        self.check()?;
        self.stage_unchecked()
    }

    /// Makes the staging place without asking about the old output now (the commit asks;
    /// for a writer whose command checked its target when it started).
    fn stage_unchecked(self) -> Result<Staged, FileError> {
        let folder = matches!(self.shape, Shape::Folder(_));
        let staging = fresh_beside(&self.path, "new", folder).map_err(|e| {
            self.fail(format!(
                "cannot write beside it ({e}); choose a writable place for the {}",
                self.what
            ))
        })?;
        Ok(Staged {
            output: self,
            staging,
            done: false,
        })
    }
}

impl Staged {
    /// Where to write the output: an empty file or an empty folder beside its place.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Puts the written output in place: the old one (checked again to be cps's) is moved
    /// aside, the new one moved in, then what cps made of the old one removed. Returns
    /// where the old one's remains are kept, if something not cps's appeared in it since
    /// the check (nothing is then removed).
    pub fn commit(mut self) -> Result<Option<PathBuf>, FileError> {
        let out = self.output.clone();
        let keep = |this: &mut Self, why: String| {
            this.done = true; // the new output stays where it is
            out.fail(format!(
                "{why}; the new {} is kept in {}",
                out.what,
                this.staging.display()
            ))
        };
        match fs::symlink_metadata(&out.path) {
            Err(e) if e.kind() == ErrorKind::NotFound => {
                self.move_in_fresh().map_err(|why| keep(&mut self, why))?;
                self.done = true;
                return Ok(None);
            }
            Err(e) => return Err(keep(&mut self, format!("cannot be inspected ({e})"))),
            Ok(_) => {}
        }
        if let Err(e) = out.check() {
            let why = if out.force {
                format!("changed while cps worked ({e})")
            } else {
                "something appeared there while cps worked, and it is left alone".into()
            };
            return Err(keep(&mut self, why));
        }
        let aside = free_beside(&out.path, "old");
        fs::rename(&out.path, &aside)
            .map_err(|e| keep(&mut self, format!("cannot be moved aside ({e})")))?;
        if let Err(e) = fs::rename(&self.staging, &out.path) {
            let back = fs::rename(&aside, &out.path);
            let old = if back.is_ok() {
                "the old one is back in place".to_string()
            } else {
                format!("the old one is in {}", aside.display())
            };
            return Err(keep(
                &mut self,
                format!("cannot be put in place ({e}); {old}"),
            ));
        }
        self.done = true;
        Ok(remove_old(&aside, &out.shape))
    }

    /// Moves the new output into a place nothing held at the check; if something appeared
    /// there meanwhile, it is left alone.
    fn move_in_fresh(&self) -> Result<(), String> {
        let path = &self.output.path;
        match &self.output.shape {
            Shape::File(_) => match fs::hard_link(&self.staging, path) {
                // A hard link is made only where nothing is: the no-replace rename.
                Ok(()) => {
                    fs::remove_file(&self.staging).ok();
                    Ok(())
                }
                Err(e) if e.kind() == ErrorKind::AlreadyExists => {
                    Err("something appeared there while cps worked, and it is left alone".into())
                }
                Err(_) => fs::rename(&self.staging, path).map_err(|e| e.to_string()),
            },
            // Renaming a folder onto a non-empty one fails: what appeared stays.
            Shape::Folder(_) => fs::rename(&self.staging, path).map_err(|e| {
                format!(
                    "cannot be put in place ({e}; did something appear there while cps worked?)"
                )
            }),
        }
    }
}

/// Removes the old output moved aside: its file, or the files and folders cps writes in
/// it, each without following a link. What remains (something that appeared since the
/// check) is kept, and its place returned.
fn remove_old(aside: &Path, shape: &Shape) -> Option<PathBuf> {
    match shape {
        Shape::File(_) => fs::remove_file(aside).err().map(|_| aside.to_path_buf()),
        Shape::Folder(files) => {
            for f in files {
                let p = aside.join(f);
                if fs::symlink_metadata(&p).is_ok_and(|m| m.is_file()) {
                    fs::remove_file(&p).ok();
                }
            }
            let mut dirs: Vec<PathBuf> = files
                .iter()
                .flat_map(|f| Path::new(f).ancestors().skip(1).map(Path::to_path_buf))
                .filter(|d| !d.as_os_str().is_empty())
                .collect();
            dirs.sort_by_key(|d| std::cmp::Reverse(d.components().count()));
            dirs.dedup();
            for d in dirs {
                fs::remove_dir(aside.join(d)).ok();
            }
            fs::remove_dir(aside).err().map(|_| aside.to_path_buf())
        }
    }
}

impl Drop for Staged {
    /// An output not committed: what was staged is removed. The staging place was made
    /// fresh by this writer (`create_new`/`create_dir` under a hidden name of this process)
    /// and only the writer writes into it, so all in it is cps's, half-written files
    /// included; `remove_dir_all` removes links in it, never what they point to.
    fn drop(&mut self) {
        if !self.done {
            match self.output.shape {
                Shape::File(_) => fs::remove_file(&self.staging).ok(),
                Shape::Folder(_) => fs::remove_dir_all(&self.staging).ok(),
            };
        }
    }
}

/// Writes `bytes` as the output's file: beside, then in place. The old output is asked
/// about at the swap (the command checked it when it started, [`Output::check`]): one that
/// may not be replaced is left alone, and the new file kept beside it.
pub fn write_file(output: Output, bytes: &[u8]) -> Result<Option<PathBuf>, FileError> {
    use std::io::Write;
    let staged = output.stage_unchecked()?;
    let written = fs::OpenOptions::new()
        .write(true)
        .truncate(true)
        .open(staged.path())
        .and_then(|mut f| f.write_all(bytes).and_then(|()| f.sync_all()));
    if let Err(e) = written {
        return Err(FileError::output(
            &staged.output.path,
            format!("cannot be written ({e})"),
        ));
    }
    staged.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILES: [&str; 3] = ["meta/info.json", "meta/stats.json", "data/file-000.parquet"];

    fn dataset(root: &Path, tag: &str) {
        for f in FILES {
            let p = root.join(f);
            fs::create_dir_all(p.parent().unwrap()).unwrap();
            fs::write(p, tag).unwrap();
        }
    }

    fn folder(path: &Path, force: bool) -> Output {
        Output::new(path, "dataset", Shape::folder(&FILES), force)
    }

    fn write_folder(out: Output, tag: &str) -> Result<Option<PathBuf>, FileError> {
        let staged = out.stage()?;
        dataset(staged.path(), tag);
        staged.commit()
    }

    fn listing(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_folder_is_written_then_replaced_only_when_forced() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("ds");
        write_folder(folder(&out, false), "one").unwrap();
        assert_eq!(fs::read_to_string(out.join(FILES[0])).unwrap(), "one");
        let e = write_folder(folder(&out, false), "two")
            .unwrap_err()
            .to_string();
        assert!(e.contains("--force replaces it"), "{e}");
        assert_eq!(write_folder(folder(&out, true), "two").unwrap(), None);
        assert_eq!(fs::read_to_string(out.join(FILES[2])).unwrap(), "two");
        // Nothing is left beside it: no staging, no old copy.
        assert_eq!(listing(dir.path()), ["ds"]);
    }

    #[test]
    fn force_never_writes_or_removes_through_a_link() {
        let dir = tempfile::tempdir().unwrap();
        let other = dir.path().join("other");
        dataset(&other, "precious");
        let link = dir.path().join("ds");
        std::os::unix::fs::symlink(&other, &link).unwrap();
        let e = write_folder(folder(&link, true), "new")
            .unwrap_err()
            .to_string();
        assert!(e.contains("symbolic link"), "{e}");
        for f in FILES {
            assert_eq!(fs::read_to_string(other.join(f)).unwrap(), "precious");
        }
        // A link inside a folder of cps's makes it not cps's.
        let out = dir.path().join("ds2");
        dataset(&out, "mine");
        fs::remove_file(out.join(FILES[1])).unwrap();
        std::os::unix::fs::symlink(other.join(FILES[1]), out.join(FILES[1])).unwrap();
        let e = write_folder(folder(&out, true), "new")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("symbolic link") && e.contains("leaves it alone"),
            "{e}"
        );
        assert_eq!(
            fs::read_to_string(other.join(FILES[1])).unwrap(),
            "precious"
        );
    }

    #[test]
    fn anything_cps_does_not_write_keeps_the_old_output_whole() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("ds");
        dataset(&out, "old");
        fs::create_dir(out.join("videos")).unwrap();
        let e = write_folder(folder(&out, true), "new")
            .unwrap_err()
            .to_string();
        assert!(e.contains("videos") && e.contains("leaves it alone"), "{e}");
        for f in FILES {
            assert_eq!(fs::read_to_string(out.join(f)).unwrap(), "old");
        }
        assert_eq!(listing(dir.path()), ["ds"]);
    }

    #[test]
    fn a_failed_write_leaves_the_old_output_and_no_staging() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("ds");
        dataset(&out, "old");
        let staged = folder(&out, true).stage().unwrap();
        fs::write(staged.path().join("half"), "x").unwrap();
        drop(staged); // the writer failed before its commit
        assert_eq!(listing(dir.path()), ["ds"]);
        assert_eq!(fs::read_to_string(out.join(FILES[0])).unwrap(), "old");
    }

    #[test]
    fn what_appears_during_the_work_is_left_alone_and_the_new_output_kept() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("rec.csv");
        let shape = Shape::file(|p| fs::read_to_string(p).is_ok_and(|t| t.starts_with("t,")));
        let staged = Output::new(&out, "recording", shape.clone(), true)
            .stage()
            .unwrap();
        fs::write(staged.path(), "t,q\n").unwrap();
        fs::write(&out, "the user's notes").unwrap();
        let e = staged.commit().unwrap_err().to_string();
        assert!(e.contains("kept in"), "{e}");
        assert_eq!(fs::read_to_string(&out).unwrap(), "the user's notes");
        assert_eq!(listing(dir.path()).len(), 2);
        // A file cps wrote is replaced with force, and the old one is gone.
        let out2 = dir.path().join("rec2.csv");
        fs::write(&out2, "t,old\n").unwrap();
        write_file(Output::new(&out2, "recording", shape, true), b"t,new\n").unwrap();
        assert_eq!(fs::read_to_string(&out2).unwrap(), "t,new\n");
        assert_eq!(listing(dir.path()).len(), 3);
    }
}
