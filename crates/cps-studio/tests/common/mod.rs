//! Helpers shared by the studio's browser tests.

use std::process::Command;

/// A headless Chromium: `$CPS_CHROMIUM`, else `chromium-headless-shell` (Debian),
/// `chromium` or `chromium-browser` on the PATH. `None` without one, which is a failure
/// under CI (`CI` set; `.ci/run` installs it).
pub fn browser() -> Option<String> {
    let found = std::env::var("CPS_CHROMIUM").ok().or_else(|| {
        ["chromium-headless-shell", "chromium", "chromium-browser"]
            .into_iter()
            .find(|b| {
                Command::new(b)
                    .arg("--version")
                    .output()
                    .is_ok_and(|o| o.status.success())
            })
            .map(String::from)
    });
    if found.is_none() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI must provide a headless Chromium (chromium-headless-shell)"
        );
        eprintln!("skipped: no headless Chromium on the PATH");
    }
    found
}
