//! The studio over real HTTP on a loopback port: the page and its script are served from
//! the binary, `POST /api/viapoint` learns the movement, bad requests get a 400 with the
//! sentence naming the field and the server keeps serving, many clients at once are all
//! answered.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use cps_studio::{StudioConfig, StudioServer};
use serde_json::{Value, json};

/// One HTTP/1.1 exchange; the status and the body.
fn http(server: &StudioServer, method: &str, path: &str, body: &[u8]) -> (u16, String) {
    let addr = server.url().trim_start_matches("http://");
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    // A server that refuses a body early may close before it is all sent.
    let _ = s.write_all(head.as_bytes()).and_then(|_| s.write_all(body));
    let mut reply = Vec::new();
    let _ = s.read_to_end(&mut reply);
    let text = String::from_utf8_lossy(&reply).into_owned();
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status in {text:?}"));
    let body = text
        .split_once("\r\n\r\n")
        .map_or("", |(_, b)| b)
        .to_string();
    (status, body)
}

fn thesis(solver: &str) -> Value {
    json!({
        "start": [0.75, 0.02, 1.87],
        "goal": [0.55, -0.57, 1.45],
        "tau": 10.0,
        "solver": solver,
        "via": [
            {"time": 2.0, "position": [0.78, 0.60, 1.70]},
            {"time": 4.0, "position": [1.12, 0.37, 1.45]},
            {"time": 6.0, "position": [1.15, -0.15, 1.20]},
            {"time": 8.0, "position": [0.90, -0.53, 1.20]}
        ]
    })
}

fn post(server: &StudioServer, body: &Value) -> (u16, Value) {
    let (status, text) = http(server, "POST", "/api/viapoint", body.to_string().as_bytes());
    (
        status,
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}")),
    )
}

#[test]
fn the_page_and_its_script_come_from_the_binary() {
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let (status, page) = http(&server, "GET", "/", b"");
    assert_eq!(status, 200);
    assert!(page.contains("<title>cps studio</title>") && page.contains("/app.js"));
    assert!(
        !page.contains("http://") && !page.contains("https://"),
        "nothing from the internet"
    );
    let (status, script) = http(&server, "GET", "/app.js", b"");
    assert_eq!(status, 200);
    assert!(script.contains("/api/viapoint"));
    let (status, body) = http(&server, "GET", "/../../etc/passwd", b"");
    assert_eq!(status, 404, "{body}");
    let (status, _) = http(&server, "GET", "/Cargo.toml", b"");
    assert_eq!(status, 404);
}

/// The exact answer meets the task's invariants: it starts at the start, is sampled every
/// dt over τ, ends at the goal and passes the via points within their errors, which the
/// answer reports consistently with its positions; CMA-ES approaches the exact optimum
/// from above.
#[test]
fn the_api_learns_the_thesis_task() {
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let (status, a) = post(&server, &thesis("exact"));
    assert_eq!(status, 200, "{a}");
    let t: Vec<f64> = serde_json::from_value(a["t"].clone()).unwrap();
    let p: Vec<Vec<f64>> = serde_json::from_value(a["position"].clone()).unwrap();
    assert_eq!((t.len(), p.len()), (1001, 1001));
    assert!((t[1000] - 10.0).abs() < 1e-9 && (t[1] - 0.01).abs() < 1e-12);
    let dist = |q: &[f64], r: &[f64]| {
        q.iter()
            .zip(r)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    assert!(dist(&p[0], &[0.75, 0.02, 1.87]) < 1e-12, "{:?}", p[0]);
    assert!(dist(&p[1000], &[0.55, -0.57, 1.45]) < 1e-4);
    let via = thesis("exact")["via"].clone();
    for (i, e) in a["via_errors_m"].as_array().unwrap().iter().enumerate() {
        let k = (via[i]["time"].as_f64().unwrap() / 0.01).round() as usize;
        let want: Vec<f64> = serde_json::from_value(via[i]["position"].clone()).unwrap();
        let e = e.as_f64().unwrap();
        assert!(e < 1e-4, "p{}: {e}", i + 1);
        assert!((dist(&p[k], &want) - e).abs() < 1e-12);
    }
    assert_eq!(a["cost"], a["optimum_cost"]);
    assert_eq!(a["solver"], "exact");

    let mut quick = thesis("cmaes");
    quick["generations"] = json!(300);
    let (status, c) = post(&server, &quick);
    assert_eq!(status, 200, "{c}");
    let (cost, optimum) = (
        c["cost"].as_f64().unwrap(),
        c["optimum_cost"].as_f64().unwrap(),
    );
    assert!(
        cost >= optimum * (1.0 - 1e-12),
        "{cost} below the optimum {optimum}"
    );
    assert_eq!(c["generations"], 300);
    // The same request, the same answer (seeded).
    let (_, again) = post(&server, &quick);
    assert_eq!(c["cost"], again["cost"]);
}

/// Malformed JSON, NaN, wrong lengths, a via point outside τ, absurd sizes: a 400 with a
/// sentence naming the problem, and the server serves the next request.
#[test]
fn bad_requests_get_a_sentence_and_the_server_keeps_serving() {
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let bad = |body: &[u8], expected: &str| {
        let (status, text) = http(&server, "POST", "/api/viapoint", body);
        assert_eq!(status, 400, "{text}");
        let v: Value = serde_json::from_str(&text).unwrap();
        let sentence = v["error"].as_str().unwrap();
        assert!(sentence.contains(expected), "{sentence}");
    };
    bad(b"{\"start\": [1, 2", "invalid JSON: EOF while parsing");
    bad(
        b"{\"start\": [NaN], \"goal\": [0], \"tau\": 1}",
        "invalid JSON: expected value",
    );
    bad(
        b"{\"start\": [0, 0], \"goal\": [1, 1], \"tau\": 1, \"color\": 3}",
        "unknown field `color`",
    );
    let mut v = thesis("exact");
    v["goal"] = json!([0.5, 0.5]);
    bad(v.to_string().as_bytes(), "goal: must have 3 coordinates");
    let mut v = thesis("exact");
    v["via"][1]["time"] = json!(12.0);
    bad(v.to_string().as_bytes(), "via[1].time");
    let mut v = thesis("exact");
    v["via"][0]["position"][2] = json!(1e300);
    bad(v.to_string().as_bytes(), "via[0].position");
    let mut v = thesis("exact");
    v["tau"] = json!(1e9);
    bad(
        v.to_string().as_bytes(),
        "tau: must be positive with at most 20000 samples",
    );
    let mut v = thesis("exact");
    v["solver"] = json!("magic");
    bad(
        v.to_string().as_bytes(),
        "solver: \"magic\" is not one of \"cmaes\", \"exact\", \"least_squares\"",
    );
    let mut v = thesis("exact");
    v["weights"] = json!({"via": -1.0});
    bad(v.to_string().as_bytes(), "weights.via");
    let mut v = thesis("cmaes");
    v["generations"] = json!(1_000_000);
    bad(
        v.to_string().as_bytes(),
        "generations: a studio request may ask at most 2000 (got 1000000)",
    );
    let mut v = thesis("cmaes");
    v["population"] = json!(1000);
    v["generations"] = json!(2000);
    bad(v.to_string().as_bytes(), "sample evaluations, more than");
    // The library's own check, in the words of a file's and of Python's.
    let mut v = thesis("cmaes");
    v["population"] = json!(1);
    bad(
        v.to_string().as_bytes(),
        "`population` must be between 2 and 100000 (got 1)",
    );
    let huge = format!("{{\"start\": [{}]}}", vec!["0.0"; 40_000].join(","));
    bad(huge.as_bytes(), "larger than 65536 bytes");
    // Still serving.
    let (status, _) = post(&server, &thesis("exact"));
    assert_eq!(status, 200);
}

/// Eight clients at once, each alternating exact and short CMA-ES requests: every one is
/// answered (the learning pool takes them in turn, none starves).
#[test]
fn many_tabs_at_once_are_all_answered() {
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    std::thread::scope(|s| {
        for tab in 0..8 {
            let server = &server;
            s.spawn(move || {
                for k in 0..3 {
                    let mut v = thesis(if (tab + k) % 2 == 0 { "exact" } else { "cmaes" });
                    v["generations"] = json!(50);
                    v["via"][0]["position"][0] = json!(0.7 + 0.01 * tab as f64);
                    let (status, a) = post(server, &v);
                    assert_eq!(status, 200, "tab {tab}: {a}");
                }
            });
        }
    });
}

#[test]
fn a_taken_or_foreign_address_is_an_error_naming_it() {
    let first = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let taken = first.url().trim_start_matches("http://").to_string();
    let e = StudioServer::start(StudioConfig::new(&taken))
        .unwrap_err()
        .to_string();
    assert!(e.contains(&taken), "{e}");
    let e = StudioServer::start(StudioConfig::new("localhost"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not an address host:port"), "{e}");
}

/// The thesis's Panda: at rest its tool is at the task's start (thesis Table 3); the
/// learned movement executed on it ends at the goal, tracked within a tenth of a
/// millimetre; a via point out of reach is named with its distance, nothing executed.
#[test]
fn the_movement_is_executed_on_the_thesis_robot() {
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let (status, text) = http(&server, "GET", "/api/robot", b"");
    assert_eq!(status, 200, "{text}");
    let view: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(view["dof"], 7);
    let points: Vec<[f64; 3]> = serde_json::from_value(view["points"].clone()).unwrap();
    assert_eq!(points.len(), 9, "base, seven joints, tool");
    let tool = points[8];
    for (a, b) in tool.iter().zip([0.75, 0.02, 1.87]) {
        assert!((a - b).abs() < 1e-3, "{tool:?}");
    }
    let mut v = thesis("exact");
    v["robot"] = json!(true);
    let (status, a) = post(&server, &v);
    assert_eq!(status, 200, "{a}");
    let r = &a["robot"];
    assert!(r["unreachable"].is_null(), "{r}");
    let frames: Vec<Vec<[f64; 3]>> = serde_json::from_value(r["frames"].clone()).unwrap();
    assert_eq!(
        frames.len(),
        251,
        "25 poses a second over 10 s, and the last"
    );
    let end = frames.last().unwrap()[8];
    for (a, b) in end.iter().zip([0.55, -0.57, 1.45]) {
        assert!((a - b).abs() < 1e-3, "{end:?}");
    }
    assert!(r["max_tracking_error_m"].as_f64().unwrap() < 1e-4, "{r}");
    assert_eq!(r["tool"].as_array().unwrap().len(), 1001);

    v["via"][1]["position"] = json!([3.0, 0.0, 1.0]);
    let (status, a) = post(&server, &v);
    assert_eq!(status, 200, "the path is still learned: {a}");
    let why = a["robot"]["unreachable"].as_str().unwrap();
    assert!(
        why.contains("`via[1]`") && why.contains("outside the robot's reachable workspace"),
        "{why}"
    );
    assert!(a["robot"]["frames"].as_array().unwrap().is_empty());
    // Robots execute tool positions: a 2-D task is refused.
    let flat = json!({"start": [0, 0], "goal": [1, 1], "tau": 2, "robot": true});
    let (status, e) = post(&server, &flat);
    assert_eq!(status, 400);
    assert!(e["error"].as_str().unwrap().starts_with("robot:"), "{e}");
}

/// Files: an experiment's text opens as the page's task (the parser's sentence with file,
/// line and column when it is wrong), the page's task saves as a file that opens back to
/// the same task, and a studio started with a file serves its task first.
#[test]
fn experiment_files_open_save_and_start_the_page() {
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let shipped = include_str!("../../../experiments/viapoint.toml");
    let body = json!({"name": "viapoint.toml", "text": shipped});
    let (status, text) = http(&server, "POST", "/api/open", body.to_string().as_bytes());
    assert_eq!(status, 200, "{text}");
    let opened: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(opened["via"].as_array().unwrap().len(), 4);
    assert_eq!(opened["weights"]["via"], 100000.0);
    let bad = json!({"name": "bad.toml", "text": shipped.replace("tau = 10.0", "tau = -1.0")});
    let (status, text) = http(&server, "POST", "/api/open", bad.to_string().as_bytes());
    assert_eq!(status, 400);
    assert!(text.contains("bad.toml:") && text.contains("tau"), "{text}");

    let mut task = thesis("exact");
    task["via"][0]["position"] = json!([0.8, 0.5, 1.65]);
    let save = json!({"name": "moved", "task": task});
    let (status, file) = http(&server, "POST", "/api/save", save.to_string().as_bytes());
    assert_eq!(status, 200, "{file}");
    assert!(file.contains("kind = \"viapoint\"") && file.contains("position = [0.8, 0.5, 1.65]"));
    let body = json!({"name": "moved.toml", "text": file});
    let (status, text) = http(&server, "POST", "/api/open", body.to_string().as_bytes());
    assert_eq!(status, 200, "{text}");
    let back: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(back["via"][0]["position"], json!([0.8, 0.5, 1.65]));
    assert_eq!(back["name"], "moved");
    let (status, _) = http(&server, "GET", "/api/initial", b"");
    assert_eq!(status, 404, "no file was opened with this studio");

    let mut config = StudioConfig::new("127.0.0.1:0");
    config.initial = Some(
        cps_studio::files::open_text("moved.toml", back_text(&back).as_str())
            .unwrap_or_else(|e| panic!("{e}")),
    );
    let with_file = StudioServer::start(config).unwrap();
    let (status, text) = http(&with_file, "GET", "/api/initial", b"");
    assert_eq!(status, 200);
    let initial: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(initial["via"][0]["position"], json!([0.8, 0.5, 1.65]));
}

/// The saved file of an opened task (through the library, as the CLI's `studio FILE`).
fn back_text(task: &Value) -> String {
    let request: cps_studio::api::ViaPointRequest = serde_json::from_value(json!({
        "start": task["start"], "goal": task["goal"], "tau": task["tau"],
        "via": task["via"], "solver": "exact"
    }))
    .unwrap();
    cps_studio::files::save(&request, "moved").unwrap()
}

/// The robot's movement as files for ROS 2 and viewers, as `cps-cli export` writes them;
/// every answer on the robot carries its limit check.
#[test]
fn the_robot_movement_exports_and_reports_its_limits() {
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let mut task = thesis("exact");
    task["robot"] = json!(true);
    let (status, a) = post(&server, &task);
    assert_eq!(status, 200);
    let usage = &a["robot"]["limit_usage"];
    assert!(usage["peak_usage"]["velocity"].is_array(), "{usage}");
    // The thesis's start configuration has joint 4 just beyond its upper limit.
    assert_eq!(usage["ok"], false);
    assert!(!a["robot"]["limit_lines"].as_array().unwrap().is_empty());
    // Without the limit check (the page's answers while dragging).
    task["limits"] = json!(false);
    let (status, quick) = post(&server, &task);
    assert_eq!(status, 200);
    assert!(
        quick["robot"]["limit_usage"].is_null(),
        "{}",
        quick["robot"]["limit_usage"]
    );
    assert_eq!(quick["robot"]["frames"], a["robot"]["frames"]);

    let export = |format: &str| {
        let body = json!({"format": format, "task": thesis("exact")});
        http(&server, "POST", "/api/export", body.to_string().as_bytes())
    };
    let (status, yaml) = export("ros2-yaml");
    assert_eq!(status, 200, "{yaml}");
    assert!(
        yaml.contains("joint_names:") && yaml.contains("panda_joint7"),
        "{}",
        &yaml[..yaml.len().min(400)]
    );
    let (status, mcap) = export("mcap");
    assert_eq!(status, 200);
    assert!(mcap.contains("MCAP0"), "the MCAP magic");
    let (status, csv) = export("csv-1khz");
    assert_eq!(status, 200);
    assert_eq!(
        csv.lines().count(),
        10_002,
        "a header and 1 kHz rows over 10 s"
    );
    let (status, e) = export("pdf");
    assert_eq!(status, 400);
    assert!(e.contains("format:"), "{e}");
}

/// Imitation mode: three demonstrations (the shipped one, shifted by 0, 1 and 2 cm in x)
/// imitated by a DMP within a millimetre; their ProMP's mean starts at the demonstrations'
/// mean start and its σ in x is the offsets' sample standard deviation (1 cm); bad files
/// are named with the line.
#[test]
fn demonstrations_are_imitated_with_their_promp_band() {
    let server = StudioServer::start(StudioConfig::new("127.0.0.1:0")).unwrap();
    let shipped = include_str!("../../../experiments/demos/table3_min_jerk.csv");
    let shifted = |dx: f64| {
        let mut out = String::from("time,x,y,z\n");
        for line in shipped.lines().skip(1) {
            let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            out.push_str(&format!("{},{},{},{}\n", v[0], v[1] + dx, v[2], v[3]));
        }
        out
    };
    let demos: Vec<Value> = (0..3)
        .map(|i| json!({"name": format!("d{i}.csv"), "text": shifted(0.01 * i as f64)}))
        .collect();
    let body = json!({"demos": demos, "bases": 30});
    let (status, text) = http(&server, "POST", "/api/imitate", body.to_string().as_bytes());
    assert_eq!(status, 200, "{}", &text[..text.len().min(300)]);
    let a: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(a["names"], json!(["x", "y", "z"]));
    for r in a["rmse"].as_array().unwrap() {
        assert!(r.as_f64().unwrap() < 1e-3, "{r}");
    }
    let mean0: Vec<f64> = serde_json::from_value(a["promp"]["mean"][0].clone()).unwrap();
    assert!(
        (mean0[0] - 0.76).abs() < 1e-3 && (mean0[2] - 1.87).abs() < 1e-3,
        "{mean0:?}"
    );
    let std0: Vec<f64> = serde_json::from_value(a["promp"]["std"][0].clone()).unwrap();
    assert!((std0[0] - 0.01).abs() < 5e-4, "σx {}", std0[0]);
    assert!(std0[1] < 1e-4 && std0[2] < 1e-4, "{std0:?}");

    // Conditioned on passing (0.80, 0.30, 1.60) at 5 s exactly: the conditioned mean
    // meets it there with no spread left.
    let body = json!({"demos": demos, "bases": 30, "via": [{"time": 5.0, "position": [0.80, 0.30, 1.60]}]});
    let (status, text) = http(&server, "POST", "/api/imitate", body.to_string().as_bytes());
    assert_eq!(status, 200, "{}", &text[..text.len().min(300)]);
    let c: Value = serde_json::from_str(&text).unwrap();
    let t: Vec<f64> = serde_json::from_value(c["promp"]["t"].clone()).unwrap();
    let k = t
        .iter()
        .position(|x| (x - 5.0).abs() < 1e-9)
        .expect("5 s on the grid");
    let mean: Vec<f64> = serde_json::from_value(c["promp"]["conditioned"][0][k].clone()).unwrap();
    let std: Vec<f64> = serde_json::from_value(c["promp"]["conditioned"][1][k].clone()).unwrap();
    for (m, want) in mean.iter().zip([0.80, 0.30, 1.60]) {
        assert!((m - want).abs() < 1e-6, "{mean:?}");
    }
    assert!(std.iter().all(|s| *s < 1e-4), "{std:?}");

    let bad = |body: Value, expected: &str| {
        let (status, text) = http(&server, "POST", "/api/imitate", body.to_string().as_bytes());
        assert_eq!(status, 400, "{text}");
        assert!(text.contains(expected), "{text}");
    };
    bad(json!({"demos": []}), "demos: give 1 to 50");
    let broken = shipped.replacen("0.749999975", "nan", 1);
    bad(
        json!({"demos": [{"name": "broken.csv", "text": broken}]}),
        "broken.csv",
    );
    let flat = "time,x,y\n0,0,0\n0.1,0.1,0.1\n0.2,0.2,0.2\n0.3,0.3,0.3\n0.4,0.4,0.4\n";
    bad(
        json!({"demos": [{"name": "a.csv", "text": shipped}, {"name": "b.csv", "text": flat}]}),
        "b.csv: 2 dimensions",
    );
    bad(
        json!({"demos": [{"name": "a.csv", "text": shipped}], "method": "magic"}),
        "method:",
    );
    bad(
        json!({"demos": [{"name": "a.csv", "text": shipped}], "via": [{"time": 1.0, "position": [0.0, 0.0, 0.0]}]}),
        "via: conditioning needs a ProMP",
    );
}
