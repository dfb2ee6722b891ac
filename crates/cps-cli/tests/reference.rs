//! docs/cli.md, the command reference, against the binary: every command the binary has
//! is in it, each with the help the binary prints, word for word.
//!
//! After changing a command's arguments, `CPS_WRITE_CLI_DOC=1 cargo test -p cps-cli
//! --test reference` rewrites the help blocks (the prose around them stays).

mod common;

use common::{cli, repo};

/// The subcommands a help text lists under `Commands:` (without `help`).
fn subcommands(help: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut inside = false;
    for line in help.lines() {
        if line.trim_end() == "Commands:" {
            inside = true;
            continue;
        }
        if inside {
            if !line.starts_with("  ") {
                break;
            }
            // A command's name starts at the third column; a wrapped description is
            // indented further.
            if line.as_bytes().get(2).is_some_and(|b| *b != b' ') {
                let name = line.split_whitespace().next().unwrap_or_default();
                if name != "help" {
                    names.push(name.to_owned());
                }
            }
        }
    }
    names
}

/// The help of `cps-cli PATH --help`.
fn help(path: &[String]) -> String {
    let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
    args.push("--help");
    let o = cli(&args);
    assert!(o.status.success(), "cps-cli {} failed", args.join(" "));
    String::from_utf8(o.stdout).expect("help is UTF-8")
}

/// Every command path of the binary, parents before their subcommands, with its help.
fn every_help() -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut todo = vec![Vec::<String>::new()];
    while let Some(path) = todo.pop() {
        let text = help(&path);
        for sub in subcommands(&text).into_iter().rev() {
            let mut child = path.clone();
            child.push(sub);
            todo.push(child);
        }
        out.push((path.join(" "), text));
    }
    out
}

/// The help blocks of docs/cli.md: each path with the range of its block's text.
fn blocks(doc: &str) -> Vec<(String, std::ops::Range<usize>)> {
    const MARK: &str = "<!-- help:";
    const OPEN: &str = "```text\n";
    let mut found = Vec::new();
    let mut at = 0;
    while let Some(i) = doc[at..].find(MARK) {
        let start = at + i + MARK.len();
        let end = start
            + doc[start..]
                .find("-->")
                .expect("a help marker ends with -->");
        let path = doc[start..end].trim().to_owned();
        let rest = &doc[end + 3..];
        let open = rest
            .find(OPEN)
            .expect("a ```text block follows each help marker");
        assert!(
            rest[..open].trim().is_empty(),
            "the help block of `{path}` must follow its marker"
        );
        let body = end + 3 + open + OPEN.len();
        let close = body + doc[body..].find("```\n").expect("a help block ends");
        found.push((path, body..close));
        at = close;
    }
    found
}

#[test]
fn the_command_reference_is_the_binarys_help() {
    let file = repo("docs/cli.md");
    let doc = std::fs::read_to_string(&file).unwrap();
    let helps = every_help();
    assert!(helps.len() > 30, "only {} commands found", helps.len());
    let found = blocks(&doc);

    let documented: Vec<&str> = found.iter().map(|(p, _)| p.as_str()).collect();
    let missing: Vec<&str> = helps
        .iter()
        .map(|(p, _)| p.as_str())
        .filter(|p| !documented.contains(p))
        .collect();
    let stale: Vec<&str> = documented
        .iter()
        .copied()
        .filter(|p| !helps.iter().any(|(h, _)| h == p))
        .collect();
    assert!(
        missing.is_empty() && stale.is_empty(),
        "docs/cli.md: commands without a help block {missing:?}, blocks of no command {stale:?}"
    );

    if std::env::var_os("CPS_WRITE_CLI_DOC").is_some() {
        let mut text = doc.clone();
        for (path, range) in found.iter().rev() {
            let (_, h) = helps.iter().find(|(p, _)| p == path).unwrap();
            text.replace_range(range.clone(), h);
        }
        std::fs::write(&file, text).unwrap();
        return;
    }
    for (path, range) in &found {
        let (_, h) = helps.iter().find(|(p, _)| p == path).unwrap();
        assert_eq!(
            &doc[range.clone()],
            h.as_str(),
            "docs/cli.md: the help of `cps-cli {path}` differs from the binary's; \
             CPS_WRITE_CLI_DOC=1 cargo test --profile checked -p cps-cli --test reference rewrites it"
        );
    }
}

/// README's experiment file is valid as printed, runs, and learns what README says: the
/// via point within 10 µm, the exact optimum's cost.
#[test]
fn the_readmes_experiment_file_runs_as_printed() {
    let readme = std::fs::read_to_string(repo("README.md")).unwrap();
    let section = readme
        .split("## An experiment file")
        .nth(1)
        .expect("README has an experiment file section");
    let start = section.find("```toml\n").expect("a TOML block") + "```toml\n".len();
    let text = &section[start..start + section[start..].find("```").unwrap()];
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("mine.toml");
    std::fs::write(&file, text).unwrap();
    let o = cli(&["check", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("out");
    let o = cli(&[
        "run",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = common::json(&out.join("summary.json"));
    let via = summary["via_errors_m"][0].as_f64().unwrap();
    assert!(via < 1e-5, "via point missed by {via} m");
    let gap = summary["gap_to_optimum"].as_f64().unwrap();
    assert!(gap.abs() < 1e-6, "gap to the exact optimum {gap}");
}
