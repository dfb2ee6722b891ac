//! A real mouse drag in headless Chromium, driven through the DevTools protocol: press on
//! via point p1, move the mouse in steps, release. The page re-learns on every move
//! (exact) and on release (CMA-ES), the path and the numbers change, and the page's own
//! measurements — gesture to redrawn path, per solver; the robot animation's frame rate —
//! are written to `studio-screenshots/latency.json` for the closing notes (measured, not
//! asserted: timing goals live in benchmarks). Skipped without a browser, except under CI.

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use cps_studio::{StudioConfig, StudioServer};
use serde_json::{Value, json};
use tungstenite::{Message, WebSocket};

/// A page of a headless browser, spoken to over the DevTools protocol.
struct Page {
    browser: Child,
    socket: WebSocket<TcpStream>,
    next_id: u64,
    _profile: tempfile::TempDir,
}

impl Page {
    fn open(browser: &str, url: &str) -> Self {
        let profile = tempfile::tempdir().unwrap();
        let mut child = Command::new(browser)
            .args([
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                "--no-first-run",
                "--disable-background-networking",
                "--remote-debugging-port=0",
                "--window-size=1280,800",
            ])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg(url)
            .stderr(Stdio::piped())
            .stdout(Stdio::null())
            // A group of its own, ended as a whole: Debian's chromium-headless-shell is a
            // script that runs the browser as its child, which outlives a killed script.
            .process_group(0)
            .spawn()
            .unwrap();
        // "DevTools listening on ws://127.0.0.1:PORT/devtools/browser/…"
        let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let port = loop {
            let line = lines.next().expect("the browser ended").unwrap();
            if let Some(rest) = line.split("ws://127.0.0.1:").nth(1) {
                break rest.split('/').next().unwrap().to_string();
            }
        };
        // Keep draining the browser's messages so it never blocks on a full pipe.
        std::thread::spawn(move || for _ in lines {});
        // The page target appears shortly after the endpoint.
        let deadline = Instant::now() + Duration::from_secs(20);
        let ws = loop {
            let list = http_get(&format!("127.0.0.1:{port}"), "/json/list");
            let targets: Value = serde_json::from_str(&list).unwrap_or(Value::Null);
            let page = targets.as_array().and_then(|t| {
                t.iter()
                    .find(|t| t["type"] == "page")
                    .and_then(|t| t["webSocketDebuggerUrl"].as_str())
                    .map(String::from)
            });
            match page {
                Some(ws) => break ws,
                None if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(50)),
                None => panic!("no page target: {list}"),
            }
        };
        let stream = TcpStream::connect(format!("127.0.0.1:{port}")).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(60)))
            .unwrap();
        let (socket, _) = tungstenite::client(ws.as_str(), stream).unwrap();
        Self {
            browser: child,
            socket,
            next_id: 1,
            _profile: profile,
        }
    }

    /// Sends a command and returns its result (events in between are skipped).
    fn call(&mut self, method: &str, params: Value) -> Value {
        let id = self.next_id;
        self.next_id += 1;
        let msg = json!({"id": id, "method": method, "params": params});
        self.socket.send(Message::text(msg.to_string())).unwrap();
        loop {
            if let Message::Text(t) = self.socket.read().unwrap() {
                let v: Value = serde_json::from_str(&t).unwrap();
                if v["id"] == id {
                    assert!(v["error"].is_null(), "{method}: {v}");
                    return v["result"].clone();
                }
            }
        }
    }

    /// The value of a JavaScript expression (JSON-able).
    fn eval(&mut self, expression: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({"expression": expression, "returnByValue": true, "awaitPromise": true}),
        );
        assert!(r["exceptionDetails"].is_null(), "{expression}: {r}");
        r["result"]["value"].clone()
    }

    /// Waits until `expression` is true (at most 30 s; an expression that throws, as on
    /// a page still loading, counts as false).
    fn until(&mut self, expression: &str) {
        let deadline = Instant::now() + Duration::from_secs(30);
        let guarded =
            format!("(() => {{ try {{ return {expression}; }} catch (e) {{ return false; }} }})()");
        while self.eval(&guarded) != json!(true) {
            assert!(Instant::now() < deadline, "never: {expression}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn mouse(&mut self, kind: &str, x: f64, y: f64) {
        let mut p = json!({"type": kind, "x": x, "y": y, "button": "left", "buttons": 1});
        if kind != "mouseMoved" {
            p["clickCount"] = json!(1);
        }
        self.call("Input.dispatchMouseEvent", p);
    }
}

impl Drop for Page {
    fn drop(&mut self) {
        // The browser's whole process group (the script, the browser and its helpers).
        let group = format!("-{}", self.browser.id());
        let _ = Command::new("kill").args(["-KILL", "--", &group]).status();
        let _ = self.browser.kill();
        let _ = self.browser.wait();
    }
}

/// One GET; the body, read by its Content-Length (the browser keeps connections open).
fn http_get(addr: &str, path: &str) -> String {
    let s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(
        &s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut reader = BufReader::new(s);
    let mut length = 0;
    loop {
        let mut line = String::new();
        reader.read_line(&mut line).unwrap();
        if line.trim().is_empty() {
            break;
        }
        if let Some((k, v)) = line.split_once(':')
            && k.eq_ignore_ascii_case("content-length")
        {
            length = v.trim().parse().unwrap();
        }
    }
    let mut body = vec![0; length];
    reader.read_exact(&mut body).unwrap();
    String::from_utf8(body).unwrap()
}

fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

#[test]
fn dragging_p1_with_the_mouse_relearns_and_redraws() {
    let Some(browser) = common::browser() else {
        return;
    };
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let mut page = Page::open(&browser, &format!("{}/", server.url()));
    page.until("document.body.dataset.learned === '1'");
    // Turning the view with the mouse (pressed away from every way point) turns the
    // drawn robot: the view's angles and the 3-D view's pixels change.
    let shown = page.eval("studio.census()");
    assert!(shown["drawn"].as_u64() > Some(10_000), "{shown}");
    let yaw = page.eval("studio.view.yaw");
    let (ox, oy) = (1200.0, 700.0);
    page.mouse("mousePressed", ox, oy);
    for k in 1..=20 {
        page.mouse("mouseMoved", ox - 4.0 * k as f64, oy);
    }
    page.mouse("mouseReleased", ox - 80.0, oy);
    let turned = page.eval("studio.census()");
    assert_ne!(page.eval("studio.view.yaw"), yaw, "the view turned");
    assert_ne!(turned["sum"], shown["sum"], "the drawn robot turned");
    assert_eq!(
        page.eval("document.body.dataset.learned"),
        "1",
        "nothing re-learned"
    );

    let before = page.eval("studio.state.via[0].position");
    let p1_error_before = page.eval("studio.state.path.via_errors_m[0]");
    let start = page.eval("studio.screenOf(0)");
    let (x0, y0) = (start[0].as_f64().unwrap(), start[1].as_f64().unwrap());

    // Press on p1, move 30 px left and 15 px down in 30 steps (≈ 7 cm), release.
    page.mouse("mousePressed", x0, y0);
    for k in 1..=30 {
        let (x, y) = (x0 - k as f64, y0 + 0.5 * k as f64);
        page.mouse("mouseMoved", x, y);
        std::thread::sleep(Duration::from_millis(15));
    }
    page.mouse("mouseReleased", x0 - 30.0, y0 + 15.0);
    page.until("studio.latencies.cmaes.length === 1");
    let after = page.eval("studio.state.via[0].position");
    assert_ne!(before, after, "p1 moved");
    let moved: f64 = (0..3)
        .map(|d| (after[d].as_f64().unwrap() - before[d].as_f64().unwrap()).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(moved > 0.03, "p1 moved {moved} m");
    // The path passes the moved p1 (the CMA-ES answer is the last one drawn).
    let p1_error = page
        .eval("studio.state.path.via_errors_m[0]")
        .as_f64()
        .unwrap();
    assert!(
        p1_error < 1e-3,
        "p1 error {p1_error} (before: {p1_error_before})"
    );
    assert_eq!(page.eval("studio.state.path.solver"), "cmaes");
    let shown =
        page.eval("document.querySelector('tr[data-name=\"p1 error\"] td:last-child').textContent");
    assert!(shown.as_str().unwrap().ends_with(" mm"), "{shown}");
    // Every exact answer of the drag was drawn; fewer than the moves (moves arriving
    // while one is in flight are merged into the next request).
    let exact: Vec<f64> = serde_json::from_value(page.eval("studio.latencies.exact")).unwrap();
    assert!(
        !exact.is_empty() && exact.len() <= 30,
        "{} exact answers",
        exact.len()
    );
    let cmaes: Vec<f64> = serde_json::from_value(page.eval("studio.latencies.cmaes")).unwrap();

    // The robot animation: play two seconds of it.
    assert!(
        page.eval("studio.state.path.robot.frames.length").as_u64() > Some(0),
        "the robot executed the dragged movement: {}",
        page.eval("studio.state.path.robot.unreachable")
    );
    page.eval("document.getElementById('play').click(), true");
    std::thread::sleep(Duration::from_secs(2));
    let fps: f64 = page
        .eval("Number(document.body.dataset.fps || 0)")
        .as_f64()
        .unwrap();
    assert!(fps > 0.0, "the animation ran");

    // Imitation mode: two demonstrations given to the page as files would be.
    let demo = include_str!("../../../experiments/demos/table3_min_jerk.csv");
    let mut shifted = String::from("time,x,y,z\n");
    for line in demo.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        shifted.push_str(&format!("{},{},{},{}\n", v[0], v[1], v[2] + 0.03, v[3]));
    }
    let files = json!([{"name": "a.csv", "text": demo}, {"name": "b.csv", "text": shifted}]);
    page.eval(&format!("studio.imitateTexts({files}).then(() => true)"));
    page.until("document.body.dataset.imitated === '2'");
    assert!(page.eval("studio.state.imitation.promp !== null") == json!(true));
    let rmse = page
        .eval("Math.max(...studio.state.imitation.rmse)")
        .as_f64()
        .unwrap();
    assert!(rmse < 1e-3, "imitation RMSE {rmse}");
    // Conditioned on a via point typed into the page.
    page.eval("document.getElementById('cond-t').value = '5'; document.getElementById('cond-p').value = '1.1,0.2,1.4'; document.getElementById('cond').click(); true");
    page.until("document.body.dataset.conditioned === 'true'");

    let shots = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("studio-screenshots");
    std::fs::create_dir_all(&shots).unwrap();
    let png = page.call("Page.captureScreenshot", json!({"format": "png"}));
    let bytes = base64_decode(png["data"].as_str().unwrap());
    assert!(bytes.len() > 10_000);
    std::fs::write(shots.join("dragged.png"), bytes).unwrap();
    // The imitation panel: demonstrations, the ProMP band and its conditioned band.
    page.eval("document.getElementById('imitation').scrollIntoView(), true");
    let png = page.call("Page.captureScreenshot", json!({"format": "png"}));
    std::fs::write(
        shots.join("imitation.png"),
        base64_decode(png["data"].as_str().unwrap()),
    )
    .unwrap();
    let weight: usize = ["/", "/app.js", "/scene.js"]
        .iter()
        .map(|p| http_get(server.url().trim_start_matches("http://"), p).len())
        .sum();
    // The page's own redraw (the 3-D view finished), as a browser draws on every move.
    let mut redraw: Vec<f64> = (0..20)
        .map(|_| page.eval("studio.redraw()").as_f64().unwrap())
        .collect();
    let mut e = exact.clone();
    let report = json!({
        "redraw_ms": {"median": quantile(&mut redraw, 0.5), "worst": quantile(&mut redraw, 1.0), "gl": page.eval("document.body.dataset.gl")},
        "exact_ms": {"median": quantile(&mut e, 0.5), "worst": quantile(&mut e, 1.0), "answers": exact.len()},
        "cmaes_ms": {"median": quantile(&mut cmaes.clone(), 0.5), "worst": quantile(&mut cmaes.clone(), 1.0), "answers": cmaes.len()},
        "robot_animation_fps": fps,
        "page_weight_bytes": weight,
    });
    std::fs::write(shots.join("latency.json"), report.to_string()).unwrap();
    eprintln!("{report}");
}

/// Standard base64 (the screenshot), without a dependency for it.
fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        _ => 63,
    };
    let clean: Vec<u8> = text
        .bytes()
        .filter(|c| *c != b'=' && !c.is_ascii_whitespace())
        .collect();
    let mut out = Vec::with_capacity(clean.len() * 3 / 4);
    for chunk in clean.chunks(4) {
        let v: Vec<u32> = chunk.iter().map(|c| u32::from(value(*c))).collect();
        let n = v.iter().fold(0u32, |a, b| (a << 6) | b) << (6 * (4 - v.len()));
        let bytes = [(n >> 16) as u8, (n >> 8) as u8, n as u8];
        out.extend_from_slice(&bytes[..v.len() - 1]);
    }
    out
}
