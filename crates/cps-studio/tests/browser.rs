//! The studio page in a real headless browser (Chromium: `chromium-headless-shell` from
//! Debian, or `$CPS_CHROMIUM`): it loads, learns the thesis task, moves via point p1 by
//! its address hook (`#move=…`, the page's own code path for a move) and shows the new
//! path's numbers; a move the API refuses shows the sentence next to the way points.
//! The robot is drawn with its collision hulls in WebGL, lit and shaded; a movement the
//! guard refuses opens at its collision, the bodies involved coloured.
//! Skipped without a browser, except under CI (`CI` set), where `.ci/run` installs it.
//! Screenshots stay in the test's target directory (`studio-screenshots/`).

mod common;

use std::process::Command;

use cps_studio::{StudioConfig, StudioServer};

const FLAGS: [&str; 4] = [
    "--no-sandbox",
    "--disable-gpu",
    "--hide-scrollbars",
    "--virtual-time-budget=20000",
];

fn dom(browser: &str, url: &str) -> String {
    let o = Command::new(browser)
        .args(FLAGS)
        .args(["--dump-dom", url])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The value after `marker` up to the next `<` or `"`.
fn after<'a>(dom: &'a str, marker: &str) -> &'a str {
    let rest = dom
        .split(marker)
        .nth(1)
        .unwrap_or_else(|| panic!("no {marker} in the page"));
    rest.split(['<', '"']).next().unwrap()
}

#[test]
fn moving_a_via_point_in_the_browser_redraws_the_path_and_its_numbers() {
    let Some(browser) = common::browser() else {
        return;
    };
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    // Loaded: one answer, the thesis task's numbers.
    let first = dom(&browser, &format!("{}/?census", server.url()));
    assert_eq!(after(&first, "data-learned=\""), "1");
    assert_eq!(after(&first, "data-samples=\""), "1001");
    assert_eq!(after(&first, "data-end=\""), "0.5500,-0.5700,1.4500");
    let p1_before = after(&first, "<td>p1 error</td><td>").to_string();

    // p1 moved to (0.9, 0.4, 1.6): a second answer, the inputs show the new position,
    // the path passes it within a tenth of a millimetre.
    let url = format!("{}/#move=0,0.9,0.4,1.6", server.url());
    let moved = dom(&browser, &url);
    assert_eq!(
        after(&moved, "data-learned=\""),
        "2",
        "the page learned again"
    );
    assert_eq!(
        after(&moved, "data-robot-frames=\""),
        "251",
        "the robot's poses"
    );
    let p1 = after(&moved, "<td>p1 error</td><td>");
    let mm: f64 = p1.trim_end_matches(" mm").parse().unwrap();
    assert!(mm < 0.1, "p1 error {p1} (before the move: {p1_before})");
    for v in ["0.900", "0.400", "1.600"] {
        assert!(
            moved.contains(&format!("value=\"{v}\"")) || moved.contains(v),
            "{v}"
        );
    }
    assert_eq!(after(&moved, "id=\"error\">"), "");

    // A move the API refuses: the sentence next to the way points, the old path kept.
    let refused = dom(&browser, &format!("{}/#move=0,0.9,0.4,1e9", server.url()));
    assert_eq!(after(&refused, "data-learned=\""), "1");
    let sentence = after(&refused, "id=\"points-error\">");
    assert!(sentence.starts_with("via[0].position"), "{sentence}");

    // The robot in its world: WebGL draws the hulls and the table, lit and shaded (many
    // shades of the bodies' one colour), nothing coloured, the guard's verdict "clear".
    assert_eq!(after(&first, "data-gl=\""), "true");
    let shades: usize = after(&first, "data-shades=\"").parse().unwrap();
    assert!(shades > 100, "{shades} shades: lit and shaded");
    assert_eq!(after(&first, "data-coloured=\""), "");
    assert_eq!(after(&first, "data-collision-frames=\""), "0");
    assert!(
        after(&first, "id=\"collision\">").starts_with("clear: every pair keeps the 5.0 mm margin")
    );
    // p2 a centimetre above the table: refused by the guard in a sentence; the slider
    // opens at the first pose within the margin, where the left finger and the table are
    // red, and red is on the screen.
    let into = format!("{}/?census#move=1,1.0,0.2,0.76,exact", server.url());
    let hit = dom(&browser, &into);
    let sentence = after(&hit, "id=\"collision\" class=\"hit\">");
    assert!(
        sentence.starts_with("refused: `panda_leftfinger` and `table` at t = 3.9"),
        "{sentence}"
    );
    let frames: usize = after(&hit, "data-collision-frames=\"").parse().unwrap();
    assert!(frames > 5, "{frames} poses within the margin");
    let coloured = after(&hit, "data-coloured=\"");
    for body in ["panda_leftfinger:red", "table:red"] {
        assert!(coloured.split(',').any(|c| c == body), "{coloured}");
    }
    let red: usize = after(&hit, "data-red-pixels=\"").parse().unwrap();
    assert!(red > 1000, "{red} red pixels");
    let clock: f64 = after(&hit, "id=\"clock\">")
        .trim_end_matches(" s")
        .parse()
        .unwrap();
    assert!((3.9..4.0).contains(&clock), "the slider at {clock} s");

    // Screenshots to look at.
    let shots = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("studio-screenshots");
    std::fs::create_dir_all(&shots).unwrap();
    for (name, url) in [
        ("moved.png", url.clone()),
        ("collision.png", into.clone()),
        (
            "refused.png",
            format!("{}/#move=0,0.9,0.4,1e9", server.url()),
        ),
    ] {
        let png = shots.join(name);
        let _ = std::fs::remove_file(&png);
        let o = Command::new(&browser)
            .args(FLAGS)
            .args([
                "--window-size=1280,800",
                &format!("--screenshot={}", png.display()),
                &url,
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let size = std::fs::metadata(&png).map(|m| m.len()).unwrap_or(0);
        assert!(size > 10_000, "{name}: {size} bytes");
    }
}
