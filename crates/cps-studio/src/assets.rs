//! The page, embedded in the binary: nothing is read from disk or fetched from the
//! internet.

const INDEX: &str = include_str!("../assets/index.html");
const APP: &str = include_str!("../assets/app.js");
const SCENE: &str = include_str!("../assets/scene.js");

/// The content type and bytes of an embedded asset.
pub(crate) fn get(name: &str) -> Option<(&'static str, &'static str)> {
    match name {
        "index.html" => Some(("text/html; charset=utf-8", INDEX)),
        "app.js" => Some(("text/javascript; charset=utf-8", APP)),
        "scene.js" => Some(("text/javascript; charset=utf-8", SCENE)),
        _ => None,
    }
}
