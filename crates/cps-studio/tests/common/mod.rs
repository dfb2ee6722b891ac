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
        cps_testkit::skip("no headless Chromium (chromium-headless-shell) on the PATH");
    }
    found
}
