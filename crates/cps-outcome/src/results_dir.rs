//! Where a run's results go, and the promise kept there: cps never deletes or overwrites a
//! file it did not write.
//!
//! A result directory carries `cps-manifest.json`, the list of the files cps wrote into
//! it, each with the size and SHA-256 it had when cps wrote it. A file counts as cps's only
//! while it still has that size and hash and is reached through real directories (never a
//! symbolic link), so a hand-made or copied manifest cannot make `--force` remove someone
//! else's file. The rules, checked before any work starts ([`Staging::prepare`]):
//!
//! - a path that does not exist: the results are written into a hidden staging directory
//!   beside it and renamed into place when complete (a reader never sees half a result);
//! - an empty directory (including `--out .` in an empty folder): the results are staged
//!   inside it and moved into place file by file;
//! - a directory that holds only cps's results (every entry, at every depth, is a file of
//!   its manifest, unchanged): refused without `--force`; with `--force` the files of the
//!   manifest are replaced (each file atomically) and nothing else is touched;
//! - a directory that holds anything cps did not write (no manifest, an entry not in it, a
//!   listed file whose size or hash changed, a symbolic link at any depth): refused, with or
//!   without `--force`, naming the directory and one such entry;
//! - a manifest of an earlier cps (no sizes and hashes): refused, since nothing in it can be
//!   verified;
//! - a file, a symbolic link, a literal `~`, or a place that cannot be written: refused
//!   with a sentence saying so.
//!
//! The same checks are made again when the results are moved into place: a file that
//! changed or a directory that became a link during the run is left alone.
//!
//! Staging directories are created with a fresh name (never reused, never cleared). A
//! staging directory knows the files cps asked for in it ([`Staging::path`]): only those
//! are moved into place and listed in the manifest, and a failed run removes only those
//! and then the directory if it is empty — never a whole tree.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use sha2::{Digest, Sha256};

use cps_files::replace::{Output, Shape};

use crate::InputError;
use crate::{Context, ExperimentError};

/// The manifest's file name.
pub const MANIFEST: &str = "cps-manifest.json";
/// The manifest's `format` tag.
const MANIFEST_FORMAT: &str = "cps-results";
/// The manifest's version: 2 records each file's size and SHA-256 (version 1 listed names).
const MANIFEST_VERSION: u64 = 2;
/// Prefix of the staging directories cps creates (inside a target, or beside it as
/// `.<name>.cps-staging-…`).
const STAGING_TAG: &str = "cps-staging-";

/// What the target holds, as found before the run.
#[derive(Debug)]
enum Target {
    /// Nothing there yet: stage beside it, rename into place.
    New,
    /// A directory that is empty or holds only cps's files (listed): stage inside it.
    Existing { old: Manifest },
}

/// What cps recorded of a file it wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Stamp {
    size: u64,
    sha256: String,
}

/// A manifest's files: relative path → the stamps a file there may have (one, or two while
/// a commit replaces it).
type Manifest = BTreeMap<String, Vec<Stamp>>;

/// The size and SHA-256 of a regular file, read in blocks.
fn stamp(path: &Path) -> std::io::Result<Stamp> {
    let mut f = fs::File::open(path)?;
    let mut hash = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut size = 0u64;
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        size += n as u64;
        hash.update(&buf[..n]);
    }
    let sha256 = hash.finalize().iter().map(|b| format!("{b:02x}")).collect();
    Ok(Stamp { size, sha256 })
}

/// Where a manifest's path stands in a directory.
#[derive(Debug, PartialEq, Eq)]
enum Standing {
    /// Nothing there, and every directory above it inside the target is a real directory.
    Absent,
    /// A regular file with a size and hash the manifest records for it.
    Ours,
    /// Something cps may not touch; the reason completes "`path` …".
    Foreign(String),
}

/// Judges `rel` inside `root` against the stamps `manifest` records for it.
fn standing(root: &Path, rel: &str, manifest: &Manifest) -> Standing {
    let mut at = root.to_path_buf();
    let parts: Vec<&str> = rel.split('/').collect();
    for (i, part) in parts.iter().enumerate() {
        at.push(part);
        let last = i + 1 == parts.len();
        let meta = match fs::symlink_metadata(&at) {
            Ok(m) => m,
            Err(_) => return Standing::Absent,
        };
        if meta.file_type().is_symlink() {
            return Standing::Foreign(format!(
                "is reached through a symbolic link (`{}`), which cps never writes or deletes through",
                parts[..=i].join("/")
            ));
        }
        if !last && !meta.is_dir() {
            return Standing::Foreign(format!("has `{}` in its way", parts[..=i].join("/")));
        }
        if last && !meta.is_file() {
            return Standing::Foreign("is not a regular file".into());
        }
    }
    let Some(stamps) = manifest.get(rel) else {
        return Standing::Foreign("cps did not write".into());
    };
    match stamp(&at) {
        Ok(s) if stamps.contains(&s) => Standing::Ours,
        Ok(_) => Standing::Foreign(
            "has changed since cps wrote it (its size or SHA-256 is not the manifest's)".into(),
        ),
        Err(e) => Standing::Foreign(format!("cannot be read ({e})")),
    }
}

/// The files listed in a directory's manifest with their stamps, or `None` when it has none.
fn read_manifest(dir: &Path) -> Result<Option<Manifest>, InputError> {
    let path = dir.join(MANIFEST);
    if fs::symlink_metadata(&path).is_err() {
        return Ok(None);
    }
    let text = cps_files::read::read_text(&path, cps_files::read::MAX_FILE_BYTES, "manifest")
        .map_err(|e| {
            InputError(format!(
                "{e}; cps cannot tell which files there are its own"
            ))
        })?;
    let bad = || {
        InputError(format!(
            "{}: not a manifest cps can read; cps cannot tell which files there are its own, so it leaves the directory alone (choose another --out)",
            path.display()
        ))
    };
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|_| bad())?;
    if v.get("format").and_then(|f| f.as_str()) != Some(MANIFEST_FORMAT) {
        return Err(bad());
    }
    let files = v.get("files").and_then(|f| f.as_array()).ok_or_else(bad)?;
    let mut manifest = Manifest::new();
    let mut legacy = false;
    for f in files {
        let (name, stamp) = match f {
            serde_json::Value::String(name) => {
                legacy = true;
                (name.as_str(), None)
            }
            entry => {
                let name = entry.get("path").and_then(|p| p.as_str()).ok_or_else(bad)?;
                let size = entry.get("size").and_then(|p| p.as_u64()).ok_or_else(bad)?;
                let sha256 = entry
                    .get("sha256")
                    .and_then(|p| p.as_str())
                    .ok_or_else(bad)?;
                if sha256.len() != 64 || !sha256.bytes().all(|b| b.is_ascii_hexdigit()) {
                    return Err(bad());
                }
                let sha256 = sha256.to_ascii_lowercase();
                (name, Some(Stamp { size, sha256 }))
            }
        };
        if !is_plain_relative(name) {
            return Err(bad());
        }
        let stamps = manifest.entry(name.to_string()).or_default();
        stamps.extend(stamp);
    }
    if legacy || v.get("version").and_then(|n| n.as_u64()) != Some(MANIFEST_VERSION) {
        return Err(InputError(format!(
            "{}: written by an earlier cps (or by hand) without the size and SHA-256 of each file, so cps cannot verify which files there are its own and leaves the directory alone (choose another --out, or remove the old results yourself)",
            path.display()
        )));
    }
    Ok(Some(manifest))
}

/// The first entry under `root/rel` (a directory) that is not cps's, with the reason.
fn first_foreign(root: &Path, rel: &str, manifest: &Manifest) -> Option<(String, String)> {
    let dir = if rel.is_empty() {
        root.to_path_buf()
    } else {
        root.join(rel)
    };
    let entries = match fs::read_dir(&dir) {
        Ok(e) => e,
        Err(e) => return Some((rel.to_string(), format!("cannot be listed ({e})"))),
    };
    let mut names: Vec<String> = entries
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    for name in names {
        if rel.is_empty() && (name == MANIFEST || name.starts_with(&format!(".{STAGING_TAG}"))) {
            continue;
        }
        let path = if rel.is_empty() {
            name.clone()
        } else {
            format!("{rel}/{name}")
        };
        let meta = match fs::symlink_metadata(dir.join(&name)) {
            Ok(m) => m,
            Err(e) => return Some((path, format!("cannot be looked at ({e})"))),
        };
        if meta.is_dir() {
            let prefix = format!("{path}/");
            if !manifest.keys().any(|f| f.starts_with(&prefix)) {
                return Some((path, "cps did not write".into()));
            }
            if let Some(found) = first_foreign(root, &path, manifest) {
                return Some(found);
            }
            continue;
        }
        match standing(root, &path, manifest) {
            Standing::Ours => {}
            Standing::Foreign(why) => return Some((path, why)),
            Standing::Absent => return Some((path, "vanished while cps looked".into())),
        }
    }
    None
}

/// A relative path without `..`, root or prefix components (what a manifest may list).
fn is_plain_relative(name: &str) -> bool {
    let p = Path::new(name);
    !name.is_empty()
        && p.components()
            .all(|c| matches!(c, std::path::Component::Normal(_)))
}

/// Checks that results may be written to `out` (see the module docs). Nothing is created.
fn inspect(out: &Path, force: bool) -> Result<Target, InputError> {
    let shown = out.display();
    if out.as_os_str().is_empty() {
        return Err(InputError("--out: the path is empty".into()));
    }
    if out.to_string_lossy().starts_with('~') {
        return Err(InputError(format!(
            "--out {shown}: cps does not expand `~` (a shell does, when it is not quoted); give the full path"
        )));
    }
    let meta = match fs::symlink_metadata(out) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Target::New),
        Err(e) => {
            return Err(InputError(format!(
                "--out {shown}: cannot look at it ({e}); choose another --out"
            )));
        }
    };
    if meta.file_type().is_symlink() {
        let to = fs::read_link(out)
            .map(|p| p.display().to_string())
            .unwrap_or_else(|_| "?".into());
        return Err(InputError(format!(
            "--out {shown}: is a symbolic link (to {to}); cps does not write through links, pass the directory itself"
        )));
    }
    if !meta.is_dir() {
        return Err(InputError(format!(
            "--out {shown}: exists and is not a directory; cps leaves it alone (choose another --out)"
        )));
    }
    let old = read_manifest(out)?;
    let listed = old.clone().unwrap_or_default();
    if let Some((name, why)) = first_foreign(out, "", &listed) {
        return Err(InputError(format!(
            "--out {shown}: holds `{name}`, which {why}; cps writes only into a new or empty directory or over its own unchanged results, and never touches other files (choose another --out, or move `{name}` away)"
        )));
    }
    let any = fs::read_dir(out).is_ok_and(|entries| {
        entries.flatten().any(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n != MANIFEST && !n.starts_with(&format!(".{STAGING_TAG}"))
        })
    });
    match old {
        Some(files) if any || !files.is_empty() => {
            if !force {
                return Err(InputError(format!(
                    "{shown}: already holds results ({MANIFEST} lists {} files); choose another --out or pass --force to replace them",
                    files.len()
                )));
            }
            Ok(Target::Existing { old: files })
        }
        _ => Ok(Target::Existing {
            old: Manifest::new(),
        }),
    }
}

/// A directory being filled out of sight, moved into place when complete, so no reader
/// ever sees half-written results and no file cps did not write is touched.
#[derive(Debug)]
pub struct Staging {
    tmp: PathBuf,
    target: PathBuf,
    kind: Target,
    /// The files cps asked for in `tmp` (relative paths).
    written: Mutex<BTreeSet<String>>,
    done: bool,
}

/// Creates a directory with a fresh name `base` + `n` (never an existing one).
fn fresh_dir(parent: &Path, base: &str) -> std::io::Result<PathBuf> {
    for n in 0..1000 {
        let p = parent.join(format!("{base}{n}"));
        match fs::create_dir(&p) {
            Ok(()) => return Ok(p),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("no free staging name"))
}

impl Staging {
    /// Checks `out` (see the module docs) and creates the staging directory, so a target
    /// that cannot be used fails before any work, as bad input.
    pub fn prepare(out: &Path, force: bool) -> Result<Self, InputError> {
        let kind = inspect(out, force)?;
        let pid = std::process::id();
        let tmp = match &kind {
            Target::New => {
                let parent = out
                    .parent()
                    .filter(|p| !p.as_os_str().is_empty())
                    .unwrap_or(Path::new("."));
                fs::create_dir_all(parent).map_err(|e| {
                    InputError(format!(
                        "--out {}: cannot create the folder {} ({e}); choose a writable --out",
                        out.display(),
                        parent.display()
                    ))
                })?;
                let name = out
                    .file_name()
                    .map_or("results".into(), |n| n.to_string_lossy().into_owned());
                fresh_dir(parent, &format!(".{name}.{STAGING_TAG}{pid}-"))
            }
            Target::Existing { .. } => fresh_dir(out, &format!(".{STAGING_TAG}{pid}-")),
        }
        .map_err(|e| {
            InputError(format!(
                "--out {}: cannot write there ({e}); choose a writable --out",
                out.display()
            ))
        })?;
        Ok(Self {
            tmp,
            target: out.to_path_buf(),
            kind,
            written: Mutex::new(BTreeSet::new()),
            done: false,
        })
    }

    /// Path of a file inside the staging directory, recorded as one cps writes.
    pub fn path(&self, file: &str) -> PathBuf {
        self.written
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .insert(file.to_string());
        self.tmp.join(file)
    }

    /// The recorded files that exist in the staging directory as regular files, sorted.
    fn staged_files(&self) -> Vec<String> {
        let written = self.written.lock().unwrap_or_else(|p| p.into_inner());
        written
            .iter()
            .filter(|f| fs::symlink_metadata(self.tmp.join(f)).is_ok_and(|m| m.is_file()))
            .cloned()
            .collect()
    }

    /// Writes a whole file.
    pub fn write(&self, file: &str, bytes: &[u8]) -> Result<(), ExperimentError> {
        let p = self.path(file);
        if let Some(dir) = p.parent() {
            fs::create_dir_all(dir).context_with(|| format!("cannot create {}", dir.display()))?;
        }
        let mut f =
            fs::File::create(&p).context_with(|| format!("cannot create {}", p.display()))?;
        f.write_all(bytes)
            .context_with(|| format!("cannot write {}", p.display()))?;
        Ok(())
    }

    /// Moves the finished results into place. Only files of the old manifest that are
    /// still as cps wrote them are replaced or removed, never through a symbolic link; a file
    /// that appeared in the target during the run and is not cps's stops the commit, and the
    /// results stay in the staging directory (named in the error).
    pub fn commit(mut self) -> Result<(), ExperimentError> {
        let files = self.staged_files();
        let mut new = Manifest::new();
        for f in &files {
            let s = stamp(&self.tmp.join(f))
                .context_with(|| format!("cannot read {} back", self.tmp.join(f).display()))?;
            new.insert(f.clone(), vec![s]);
        }
        match &self.kind {
            Target::New => {
                write_manifest(&self.tmp, &new)?;
                if let Err(e) = fs::rename(&self.tmp, &self.target) {
                    self.done = true; // keep the results where they are
                    return Err(ExperimentError::Message(format!(
                        "cannot move the results into {} ({e}; did something create it during the run?); they are in {}",
                        self.target.display(),
                        self.tmp.display()
                    )));
                }
            }
            Target::Existing { old } => {
                // A file that is not ours (it appeared, changed, or lies behind a link that
                // appeared during the run): stop, keep the results.
                if let Some((clash, why)) =
                    files
                        .iter()
                        .find_map(|f| match standing(&self.target, f, old) {
                            Standing::Foreign(why) => Some((f, why)),
                            _ => None,
                        })
                {
                    self.done = true;
                    return Err(ExperimentError::Message(format!(
                        "{}: `{clash}` appeared during the run or changed ({why}), so it is left alone; the results are in {}",
                        self.target.display(),
                        self.tmp.display()
                    )));
                }
                // The manifest covers old and new files at every moment.
                let mut union = old.clone();
                for (f, stamps) in &new {
                    union
                        .entry(f.clone())
                        .or_default()
                        .extend(stamps.iter().cloned());
                }
                write_manifest(&self.target, &union)?;
                for f in &files {
                    make_parents(&self.target, f)?;
                    fs::rename(self.tmp.join(f), self.target.join(f))
                        .context_with(|| format!("cannot move {f} into place"))?;
                }
                for f in old.keys().filter(|f| !new.contains_key(*f)) {
                    if standing(&self.target, f, old) == Standing::Ours {
                        fs::remove_file(self.target.join(f)).ok();
                    }
                }
                write_manifest(&self.target, &new)?;
                remove_empty_tree(&self.tmp);
            }
        }
        self.done = true;
        Ok(())
    }
}

/// Creates the directories above `rel` inside `root`, each a real directory (never
/// through a symbolic link).
fn make_parents(root: &Path, rel: &str) -> Result<(), ExperimentError> {
    let parts: Vec<&str> = rel.split('/').collect();
    let mut at = root.to_path_buf();
    for part in &parts[..parts.len() - 1] {
        at.push(part);
        match fs::symlink_metadata(&at) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => {
                return Err(ExperimentError::Message(format!(
                    "{}: is not a directory cps can write into (a link or a file appeared during the run); `{rel}` is left in the staging directory",
                    at.display()
                )));
            }
            Err(_) => {
                fs::create_dir(&at).context_with(|| format!("cannot create {}", at.display()))?
            }
        }
    }
    Ok(())
}

fn remove_empty_tree(dir: &Path) {
    if let Ok(entries) = fs::read_dir(dir) {
        for e in entries.flatten() {
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                remove_empty_tree(&e.path());
            }
        }
    }
    fs::remove_dir(dir).ok();
}

/// Writes the manifest through a temporary file and a rename.
fn write_manifest(dir: &Path, files: &Manifest) -> Result<(), ExperimentError> {
    let entries: Vec<serde_json::Value> = files
        .iter()
        .flat_map(|(path, stamps)| {
            stamps
                .iter()
                .map(move |s| serde_json::json!({"path": path, "sha256": s.sha256, "size": s.size}))
        })
        .collect();
    // Keys in alphabetical order (as manifests have always been written).
    let text = serde_json::to_string_pretty(&serde_json::json!({
        "files": entries,
        "format": MANIFEST_FORMAT,
        "version": MANIFEST_VERSION,
        "written_by": format!("cps {}", env!("CARGO_PKG_VERSION")),
    }))
    .context_with(|| "cannot encode the manifest".into())?;
    let tmp = dir.join(format!(".{MANIFEST}.tmp-{}", std::process::id()));
    fs::write(&tmp, text).context_with(|| format!("cannot write {}", tmp.display()))?;
    fs::rename(&tmp, dir.join(MANIFEST))
        .context_with(|| format!("cannot write {}", dir.join(MANIFEST).display()))?;
    Ok(())
}

impl Drop for Staging {
    /// A run that did not commit removes the files it staged and then the staging
    /// directory if nothing else is in it.
    fn drop(&mut self) {
        if !self.done {
            for f in self.staged_files() {
                fs::remove_file(self.tmp.join(f)).ok();
            }
            remove_empty_tree(&self.tmp);
        }
    }
}

/// What kind of file a single-file output is, so `--force` replaces only files cps could
/// have written.
#[derive(Debug, Clone, Copy)]
pub enum FileKind {
    /// A DMP model (`"format": "cps-dmp-model"`).
    Model,
    /// A ProMP (`"format": "cps-promp-model"`).
    ProMp,
    /// A CSV file whose header starts with `time` or `t`.
    TrajectoryCsv,
    /// A chunk file (`chunk,arrived_s,observed_s,k,q1,…`), as `franka follow` records.
    ChunkCsv,
    /// A figure: PNG or SVG.
    Figure,
    /// An MCAP file (its magic bytes).
    Mcap,
    /// A JointTrajectory in YAML flow style as `cps-cli export` writes it.
    TrajectoryYaml,
    /// A robot's calibration as `cps-cli identify` writes it (its first line says so).
    Calibration,
    /// A recording's report (`rec.report.json`: JSON saying whether the run was `complete`).
    RecordingReport,
}

/// The first line of every calibration file cps writes.
pub const CALIBRATION_HEADER: &str = "# A robot's calibration, identified by cps";

/// Whether the file at `path` is of `kind`, by its first 4 kB (never more is read).
pub fn looks_like(path: &Path, kind: FileKind) -> bool {
    let Ok(bytes) = cps_files::read::head(path, 4096, "file") else {
        return false;
    };
    let head = &bytes[..];
    let text = String::from_utf8_lossy(head);
    match kind {
        FileKind::Model => text.contains("\"cps-dmp-model\""),
        FileKind::ProMp => text.contains("\"cps-promp-model\""),
        FileKind::TrajectoryCsv => text.starts_with("time,") || text.starts_with("t,"),
        FileKind::ChunkCsv => text.starts_with("chunk,arrived_s,observed_s,k,"),
        FileKind::Mcap => head.starts_with(b"\x89MCAP0\r\n"),
        FileKind::TrajectoryYaml => text.starts_with("{header: "),
        FileKind::Calibration => text.starts_with(CALIBRATION_HEADER),
        FileKind::RecordingReport => {
            text.trim_start().starts_with('{') && text.contains("\"complete\"")
        }
        FileKind::Figure => {
            head.starts_with(b"\x89PNG\r\n\x1a\n")
                || text.trim_start().starts_with("<svg")
                || text.trim_start().starts_with("<?xml")
        }
    }
}

/// Checks the single output files of a command before any work: `out` (of `out_kind`)
/// and, when given, a figure `plot` that is not the same file.
pub fn check_file_targets(
    out: &Path,
    out_kind: FileKind,
    plot: Option<&Path>,
    force: bool,
) -> Result<(), InputError> {
    check_file_target(out, out_kind, force)?;
    if let Some(p) = plot {
        if p == out {
            return Err(InputError(format!(
                "--plot {}: is the same file as --out",
                p.display()
            )));
        }
        check_file_target(p, FileKind::Figure, force)?;
    }
    Ok(())
}

/// Checks that a single output file may be written: a new path, or with `force` an
/// existing regular file of the kind cps writes there.
pub fn check_file_target(path: &Path, kind: FileKind, force: bool) -> Result<(), InputError> {
    let shown = path.display();
    if path.to_string_lossy().starts_with('~') {
        return Err(InputError(format!(
            "{shown}: cps does not expand `~` (a shell does, when it is not quoted); give the full path"
        )));
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(InputError(format!(
            "{shown}: the folder {} does not exist; create it first or choose another path",
            parent.display()
        )));
    }
    // What may be replaced is the one writer's rule (cps-files), the same for every output.
    let shape = Shape::file(move |p| looks_like(p, kind));
    Output::new(path, "file", shape, force)
        .check()
        .map_err(InputError::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The files under `dir`, as relative paths with `/` separators.
    fn list_files(dir: &Path, prefix: &str, out: &mut Vec<String>) -> std::io::Result<()> {
        for entry in fs::read_dir(dir)? {
            let entry = entry?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let rel = if prefix.is_empty() {
                name.clone()
            } else {
                format!("{prefix}/{name}")
            };
            if entry.file_type()?.is_dir() {
                list_files(&entry.path(), &rel, out)?;
            } else {
                out.push(rel);
            }
        }
        Ok(())
    }

    /// The paths a directory's manifest lists.
    fn listed(dir: &Path) -> BTreeSet<String> {
        read_manifest(dir).unwrap().unwrap().into_keys().collect()
    }

    fn names(dir: &Path) -> BTreeSet<String> {
        let mut v = Vec::new();
        list_files(dir, "", &mut v).unwrap();
        v.into_iter().collect()
    }

    #[test]
    fn a_new_directory_gets_the_results_and_a_manifest() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("r");
        let s = Staging::prepare(&out, false).unwrap();
        s.write("a.txt", b"1").unwrap();
        s.commit().unwrap();
        assert_eq!(
            names(&out),
            ["a.txt", MANIFEST].iter().map(|s| s.to_string()).collect()
        );
        // Nothing else is left beside it.
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn only_the_files_cps_staged_are_removed_moved_or_listed() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("r");
        // A failed run leaves a stranger's file in the staging folder alone.
        let s = Staging::prepare(&out, false).unwrap();
        s.write("a.txt", b"1").unwrap();
        let stray = s.tmp.join("stray.txt");
        fs::write(&stray, b"not cps's").unwrap();
        drop(s);
        assert_eq!(fs::read(&stray).unwrap(), b"not cps's");
        assert!(!stray.with_file_name("a.txt").exists());
        // A committed run lists only what cps wrote.
        fs::create_dir(&out).unwrap();
        let s = Staging::prepare(&out, false).unwrap();
        s.write("a.txt", b"1").unwrap();
        fs::write(s.tmp.join("stray.txt"), b"x").unwrap();
        let staging = s.tmp.clone();
        s.commit().unwrap();
        let listed = listed(&out);
        assert_eq!(listed, ["a.txt".to_string()].into_iter().collect());
        assert!(!out.join("stray.txt").exists());
        assert_eq!(fs::read(staging.join("stray.txt")).unwrap(), b"x");
    }

    #[test]
    fn force_replaces_only_files_of_the_manifest() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("r");
        let s = Staging::prepare(&out, false).unwrap();
        s.write("a.txt", b"old").unwrap();
        s.write("gone.txt", b"old").unwrap();
        s.commit().unwrap();
        // Without force: refused, nothing changes.
        let e = Staging::prepare(&out, false).unwrap_err();
        assert!(e.0.contains("already holds results"), "{e}");
        let s = Staging::prepare(&out, true).unwrap();
        s.write("a.txt", b"new").unwrap();
        s.commit().unwrap();
        assert_eq!(fs::read(out.join("a.txt")).unwrap(), b"new");
        assert!(!out.join("gone.txt").exists());
        let listed = listed(&out);
        assert_eq!(listed, ["a.txt".to_string()].into_iter().collect());
    }

    #[test]
    fn a_foreign_file_is_never_touched() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("r");
        fs::create_dir(&out).unwrap();
        fs::write(out.join("thesis.pdf"), b"mine").unwrap();
        for force in [false, true] {
            let e = Staging::prepare(&out, force).unwrap_err();
            assert!(e.0.contains("`thesis.pdf`"), "{e}");
        }
        // A cps result directory with a foreign file added later: refused too.
        let out2 = d.path().join("r2");
        let s = Staging::prepare(&out2, false).unwrap();
        s.write("a.txt", b"1").unwrap();
        s.commit().unwrap();
        fs::write(out2.join("notes.txt"), b"mine").unwrap();
        let e = Staging::prepare(&out2, true).unwrap_err();
        assert!(e.0.contains("`notes.txt`"), "{e}");
        assert_eq!(fs::read(out.join("thesis.pdf")).unwrap(), b"mine");
        assert_eq!(fs::read(out2.join("notes.txt")).unwrap(), b"mine");
    }

    #[test]
    fn a_file_that_appears_during_the_run_stops_the_commit_and_keeps_both() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("r");
        fs::create_dir(&out).unwrap();
        let s = Staging::prepare(&out, false).unwrap();
        s.write("summary.json", b"{}").unwrap();
        let staged = s.path("summary.json");
        fs::write(out.join("summary.json"), b"user's").unwrap();
        let e = s.commit().unwrap_err().to_string();
        assert!(e.contains("appeared during the run"), "{e}");
        assert_eq!(fs::read(out.join("summary.json")).unwrap(), b"user's");
        assert_eq!(fs::read(staged).unwrap(), b"{}");
    }

    #[test]
    fn links_files_tildes_and_bad_manifests_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let file = d.path().join("f");
        fs::write(&file, b"x").unwrap();
        assert!(
            Staging::prepare(&file, true)
                .unwrap_err()
                .0
                .contains("not a directory")
        );
        let real = d.path().join("real");
        fs::create_dir(&real).unwrap();
        let link = d.path().join("link");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        assert!(
            Staging::prepare(&link, false)
                .unwrap_err()
                .0
                .contains("symbolic link")
        );
        assert!(
            Staging::prepare(Path::new("~/x"), false)
                .unwrap_err()
                .0
                .contains("`~`")
        );
        let bad = d.path().join("bad");
        fs::create_dir(&bad).unwrap();
        fs::write(
            bad.join(MANIFEST),
            r#"{"format":"cps-results","files":["../x"]}"#,
        )
        .unwrap();
        assert!(
            Staging::prepare(&bad, true)
                .unwrap_err()
                .0
                .contains("not a manifest")
        );
        // A dropped (failed) staging leaves nothing behind.
        let out = d.path().join("new");
        let s = Staging::prepare(&out, false).unwrap();
        s.write("a", b"1").unwrap();
        drop(s);
        assert!(!out.exists());
        assert_eq!(fs::read_dir(d.path()).unwrap().count(), 4);
    }

    #[test]
    fn single_files_are_replaced_only_when_forced_and_cps_shaped() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("model.json");
        assert!(check_file_target(&p, FileKind::Model, false).is_ok());
        fs::write(&p, b"{\"format\": \"cps-dmp-model\"}").unwrap();
        assert!(check_file_target(&p, FileKind::Model, false).is_err());
        assert!(check_file_target(&p, FileKind::Model, true).is_ok());
        let q = d.path().join("notes.csv");
        fs::write(&q, b"name,grade\n").unwrap();
        assert!(check_file_target(&q, FileKind::TrajectoryCsv, true).is_err());
    }

    /// A hostile or stale manifest never makes `--force` delete or replace a file cps did
    /// not write: not through a linked directory (inside or outside `--out`), not a file it
    /// names without a hash, not one whose content is not what cps wrote.
    #[test]
    fn force_never_follows_links_nor_trusts_a_manifest_it_cannot_verify() {
        let d = tempfile::tempdir().unwrap();
        let elsewhere = d.path().join("elsewhere");
        fs::create_dir(&elsewhere).unwrap();
        fs::write(elsewhere.join("victim.txt"), b"precious").unwrap();

        // A results directory whose `lnk` is a link to another directory, with a manifest
        // (correct size and hash) naming `lnk/victim.txt`.
        let out = d.path().join("r");
        let s = Staging::prepare(&out, false).unwrap();
        s.write("a.txt", b"1").unwrap();
        s.commit().unwrap();
        std::os::unix::fs::symlink(&elsewhere, out.join("lnk")).unwrap();
        let mut m = read_manifest(&out).unwrap().unwrap();
        m.insert(
            "lnk/victim.txt".into(),
            vec![stamp(&elsewhere.join("victim.txt")).unwrap()],
        );
        write_manifest(&out, &m).unwrap();
        let e = Staging::prepare(&out, true).unwrap_err();
        assert!(
            e.0.contains("`lnk`") && e.0.contains("symbolic link"),
            "{e}"
        );
        assert_eq!(fs::read(elsewhere.join("victim.txt")).unwrap(), b"precious");

        // The link appears during the run: the commit does not remove through it either.
        let out = d.path().join("r2");
        let s = Staging::prepare(&out, false).unwrap();
        s.write("sub/victim.txt", b"precious").unwrap();
        s.write("a.txt", b"1").unwrap();
        s.commit().unwrap();
        let s = Staging::prepare(&out, true).unwrap();
        s.write("a.txt", b"2").unwrap();
        fs::remove_file(out.join("sub/victim.txt")).unwrap();
        fs::remove_dir(out.join("sub")).unwrap();
        std::os::unix::fs::symlink(&elsewhere, out.join("sub")).unwrap();
        s.commit().unwrap();
        assert_eq!(fs::read(elsewhere.join("victim.txt")).unwrap(), b"precious");
        assert_eq!(fs::read(out.join("a.txt")).unwrap(), b"2");

        // A hand-made manifest naming a user's file, without hashes: refused, kept.
        let thesis = d.path().join("thesis");
        fs::create_dir(&thesis).unwrap();
        fs::write(thesis.join("thesis.tex"), b"\\documentclass").unwrap();
        fs::write(
            thesis.join(MANIFEST),
            r#"{"files":["thesis.tex"],"format":"cps-results","version":1}"#,
        )
        .unwrap();
        let e = Staging::prepare(&thesis, true).unwrap_err();
        assert!(e.0.contains("cannot verify"), "{e}");
        // …and with a hash that is not the file's.
        fs::write(
            thesis.join(MANIFEST),
            format!(
                r#"{{"files":[{{"path":"thesis.tex","sha256":"{}","size":14}}],"format":"cps-results","version":2}}"#,
                "0".repeat(64)
            ),
        )
        .unwrap();
        let e = Staging::prepare(&thesis, true).unwrap_err();
        assert!(
            e.0.contains("`thesis.tex`") && e.0.contains("changed"),
            "{e}"
        );
        assert_eq!(
            fs::read(thesis.join("thesis.tex")).unwrap(),
            b"\\documentclass"
        );

        // A result the user edited is theirs now: --force leaves it, before and at commit.
        let out = d.path().join("r3");
        let s = Staging::prepare(&out, false).unwrap();
        s.write("a.txt", b"1").unwrap();
        s.write("b.txt", b"1").unwrap();
        s.commit().unwrap();
        fs::write(out.join("a.txt"), b"edited").unwrap();
        let e = Staging::prepare(&out, true).unwrap_err();
        assert!(e.0.contains("`a.txt`") && e.0.contains("changed"), "{e}");
        fs::write(out.join("a.txt"), b"1").unwrap();
        let s = Staging::prepare(&out, true).unwrap();
        s.write("a.txt", b"2").unwrap();
        fs::write(out.join("b.txt"), b"edited during the run").unwrap();
        s.commit().unwrap();
        assert_eq!(
            fs::read(out.join("b.txt")).unwrap(),
            b"edited during the run"
        );
        assert_eq!(listed(&out), ["a.txt".to_string()].into_iter().collect());
    }
}
