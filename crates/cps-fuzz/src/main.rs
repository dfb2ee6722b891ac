//! `cps-fuzz`: fuzzing of cps's parsers and protocol handler on stable Rust.
//!
//! ```text
//! cargo run --profile checked -p cps-fuzz -- all --inputs 1000000        # every target
//! cargo run --profile checked -p cps-fuzz -- urdf --inputs 100000 --seed 7
//! cargo run --profile checked -p cps-fuzz -- list
//! ```
//!
//! Targets: the experiment TOML loader, TOML and URDF robots, scenes, demonstration CSV,
//! DMP model JSON, CMA-ES checkpoint JSON, and CBOR requests through the stand-in
//! server's handler. Inputs are made from valid seeds (the shipped files, and
//! `fuzz/corpus/<target>/` when it exists) by one to three mutations each: mostly
//! grammar-aware ones (a number made hostile — 0, −1, 1e300, NaN, inf, 2⁶⁴ —, a string
//! made empty, long or strange, a line dropped or repeated a thousand times, a value
//! nested 50 000 deep, a type changed, another file spliced in, the text cut), a quarter
//! raw byte mutations. Input `i` of a run depends only on `(seed, i)`, so a finding is
//! reproduced with `--seed S --start I --inputs 1`.
//!
//! A panic is caught, reported with its input (saved under `target/fuzz-findings/`) and counted; an
//! input that takes longer than `--timeout` (default 10 s) is reported as a hang and ends
//! the run; an abort ends the process (run again from the printed input number). Exit
//! code 0 only when nothing was found.

mod mutate;
mod targets;

use std::io::Write;
use std::panic::AssertUnwindSafe;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use targets::Target;

struct Options {
    which: String,
    inputs: u64,
    start: u64,
    seed: u64,
    timeout: Duration,
}

fn parse_args() -> Result<Options, String> {
    let mut args = std::env::args().skip(1);
    let mut o = Options {
        which: String::new(),
        inputs: 10_000,
        start: 0,
        seed: 1,
        timeout: Duration::from_secs(10),
    };
    let number = |flag: &str, v: Option<String>| -> Result<u64, String> {
        v.ok_or(format!("{flag} needs a value"))?
            .replace('_', "")
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite() && *x >= 0.0 && *x <= 1e15)
            .map(|x| x as u64)
            .ok_or(format!("{flag} needs a whole number"))
    };
    while let Some(a) = args.next() {
        match a.as_str() {
            "--inputs" => o.inputs = number("--inputs", args.next())?,
            "--start" => o.start = number("--start", args.next())?,
            "--seed" => o.seed = number("--seed", args.next())?,
            "--timeout" => {
                o.timeout = Duration::from_secs(number("--timeout", args.next())?.clamp(1, 3600))
            }
            "-h" | "--help" => return Err(String::new()),
            t if !t.starts_with('-') && o.which.is_empty() => o.which = t.to_string(),
            other => return Err(format!("unknown argument `{other}`")),
        }
    }
    if o.which.is_empty() {
        return Err("name a target, `all` or `list`".into());
    }
    Ok(o)
}

/// The largest input made (1 MiB).
const MAX_INPUT: usize = 1 << 20;

/// One input: a seed mutated one to three times (deterministic in `(seed, i)`).
fn make_input(target: &Target, seeds: &[Vec<u8>], run_seed: u64, i: u64) -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(run_seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ i);
    let mut input = seeds[rng.random_range(0..seeds.len())].clone();
    let others: Vec<&str> = seeds
        .iter()
        .filter_map(|s| std::str::from_utf8(s).ok())
        .collect();
    for _ in 0..rng.random_range(1..=3) {
        let next = match std::str::from_utf8(&input) {
            Ok(t) if target.text && rng.random_bool(0.75) => {
                mutate::mutate_text(t, &mut rng, &others).into_bytes()
            }
            _ => mutate::mutate_bytes(&input, &mut rng),
        };
        // Inputs stay below the size the loaders accept, where the parsers do the work
        // (larger files are refused by size before parsing).
        if next.len() <= MAX_INPUT {
            input = next;
        }
    }
    input
}

/// The extra seeds in `fuzz/corpus/<target>/`.
fn corpus(name: &str) -> Vec<Vec<u8>> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz/corpus")
        .join(name);
    let mut out = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        let mut paths: Vec<_> = entries.flatten().map(|e| e.path()).collect();
        paths.sort();
        for p in paths {
            if let Ok(b) = std::fs::read(p) {
                out.push(b);
            }
        }
    }
    out
}

/// What the watchdog sees: when the current input started, its number and bytes.
struct Current {
    started: Instant,
    index: u64,
    input: Vec<u8>,
}

fn save(target: &str, what: &str, index: u64, input: &[u8]) -> String {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/fuzz-findings");
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join(format!("{target}-{what}-{index}.bin"));
    let _ = std::fs::write(&path, input);
    path.display().to_string()
}

struct Report {
    inputs: u64,
    accepted: u64,
    panics: u64,
    seconds: f64,
}

fn fuzz(target: &Target, o: &Options) -> Report {
    let mut seeds = target.seeds.clone();
    seeds.extend(corpus(target.name));
    // Every seed itself first: they must pass.
    let current = Arc::new(Mutex::new(Current {
        started: Instant::now(),
        index: 0,
        input: Vec::new(),
    }));
    let done = Arc::new(AtomicBool::new(false));
    let watchdog = {
        let (current, done, timeout, name) =
            (current.clone(), done.clone(), o.timeout, target.name);
        std::thread::spawn(move || {
            while !done.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(50));
                let c = current.lock().unwrap_or_else(|p| p.into_inner());
                if c.started.elapsed() > timeout {
                    let path = save(name, "hang", c.index, &c.input);
                    eprintln!(
                        "HANG: {name} input {} ran longer than {timeout:?}; saved to {path}",
                        c.index
                    );
                    std::process::exit(3);
                }
            }
        })
    };
    let started = Instant::now();
    let mut report = Report {
        inputs: 0,
        accepted: 0,
        panics: 0,
        seconds: 0.0,
    };
    let feed = |index: u64, input: Vec<u8>, report: &mut Report| {
        {
            let mut c = current.lock().unwrap_or_else(|p| p.into_inner());
            c.started = Instant::now();
            c.index = index;
            c.input.clone_from(&input);
        }
        match std::panic::catch_unwind(AssertUnwindSafe(|| (target.run)(&input))) {
            Ok(true) => report.accepted += 1,
            Ok(false) => {}
            Err(e) => {
                report.panics += 1;
                let msg = e
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                let path = save(target.name, "panic", index, &input);
                eprintln!(
                    "PANIC: {} input {index}: {msg} (saved to {path})",
                    target.name
                );
            }
        }
        report.inputs += 1;
        // Forget the input before the next is made, so the watchdog never blames it.
        current.lock().unwrap_or_else(|p| p.into_inner()).started = Instant::now();
    };
    if o.start == 0 {
        for (k, s) in seeds.iter().enumerate() {
            feed(u64::MAX - k as u64, s.clone(), &mut report);
        }
    }
    let mut last = Instant::now();
    for i in o.start..o.start.saturating_add(o.inputs) {
        let input = make_input(target, &seeds, o.seed, i);
        feed(i, input, &mut report);
        if last.elapsed() > Duration::from_secs(10) {
            last = Instant::now();
            eprintln!(
                "  {}: {} inputs, {:.0}/s",
                target.name,
                report.inputs,
                report.inputs as f64 / started.elapsed().as_secs_f64()
            );
        }
    }
    done.store(true, Ordering::Relaxed);
    let _ = watchdog.join();
    report.seconds = started.elapsed().as_secs_f64();
    report
}

fn main() -> ExitCode {
    let o = match parse_args() {
        Ok(o) => o,
        Err(e) => {
            if !e.is_empty() {
                eprintln!("error: {e}");
            }
            eprintln!(
                "usage: cps-fuzz <target|all|list> [--inputs N] [--seed S] [--start I] [--timeout SECONDS]"
            );
            return ExitCode::from(2);
        }
    };
    let all = targets::all();
    if o.which == "list" {
        for t in &all {
            println!("{}", t.name);
        }
        return ExitCode::SUCCESS;
    }
    let chosen: Vec<&Target> = all
        .iter()
        .filter(|t| o.which == "all" || t.name == o.which)
        .collect();
    if chosen.is_empty() {
        eprintln!("error: no target `{}` (see `cps-fuzz list`)", o.which);
        return ExitCode::from(2);
    }
    // Panics are reported by the loop, once, with their input.
    std::panic::set_hook(Box::new(|_| {}));
    let mut found = 0;
    println!("target            inputs  accepted  panics  seconds  inputs/s");
    for t in chosen {
        let r = fuzz(t, &o);
        found += r.panics;
        println!(
            "{:<16} {:>8} {:>9} {:>7} {:>8.1} {:>9.0}",
            t.name,
            r.inputs,
            r.accepted,
            r.panics,
            r.seconds,
            r.inputs as f64 / r.seconds.max(1e-9)
        );
        let _ = std::io::stdout().flush();
    }
    if found > 0 {
        eprintln!("{found} panic(s) found");
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A short run of every target (the CI run): the seeds and 300 mutated inputs each,
    /// with no panic. The seeds themselves must be accepted.
    #[test]
    fn every_target_survives_a_short_run() {
        std::panic::set_hook(Box::new(|_| {}));
        let o = Options {
            which: "all".into(),
            inputs: 300,
            start: 0,
            seed: 2026,
            timeout: Duration::from_secs(120),
        };
        for t in targets::all() {
            for s in &t.seeds {
                assert!((t.run)(s), "{}: a seed is refused", t.name);
            }
            let r = fuzz(&t, &o);
            assert_eq!(r.panics, 0, "{}", t.name);
            assert!(r.inputs >= 300);
        }
        let _ = std::panic::take_hook();
    }

    #[test]
    fn inputs_depend_only_on_seed_and_index() {
        let t = &targets::all()[0];
        let a = make_input(t, &t.seeds, 5, 42);
        let b = make_input(t, &t.seeds, 5, 42);
        assert_eq!(a, b);
        assert_ne!(a, make_input(t, &t.seeds, 5, 43));
    }
}
