//! Records the commit this build comes from (`CPS_BUILD_COMMIT`), for `summary.json`:
//! `git rev-parse HEAD` of the checkout, `-dirty` when tracked files differ from it, or
//! `unknown` outside a git checkout (a set `CPS_BUILD_COMMIT` wins).

use std::path::Path;
use std::process::Command;

fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    println!("cargo:rerun-if-env-changed=CPS_BUILD_COMMIT");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let commit = match std::env::var("CPS_BUILD_COMMIT") {
        Ok(c) if !c.is_empty() => c,
        _ => match git(dir, &["rev-parse", "HEAD"]) {
            Some(head) => {
                // Rebuild when HEAD moves or the index changes (a commit, a checkout).
                if let Some(git_dir) = git(dir, &["rev-parse", "--absolute-git-dir"]) {
                    for f in ["HEAD", "index"] {
                        println!("cargo:rerun-if-changed={git_dir}/{f}");
                    }
                }
                // Without optional locks: a `git status` that refreshed the index would
                // change the file watched above, and the next cargo would build again.
                let status = [
                    "--no-optional-locks",
                    "status",
                    "--porcelain",
                    "--untracked-files=no",
                ];
                let dirty = git(dir, &status).is_some_and(|s| !s.is_empty());
                if dirty { format!("{head}-dirty") } else { head }
            }
            None => "unknown".into(),
        },
    };
    println!("cargo:rustc-env=CPS_BUILD_COMMIT={commit}");
}
