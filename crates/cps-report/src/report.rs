//! `report.html` (feature `figures`): one self-contained page per run — the run's own
//! table, the outcome's report tables, then every figure as inline SVG with its caption —
//! that opens offline and can be handed out.

use cps_outcome::outcome::{Outcome, ReportTable};
use cps_outcome::results_dir::Staging;
use cps_outcome::{Context, ExperimentError};

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Writes `report.html` into `stage`. With `figures`, each figure's `<name>.svg` must
/// already be in the stage; without, the figures are listed as not drawn.
pub fn write(outcome: &Outcome, stage: &Staging, figures: bool) -> Result<(), ExperimentError> {
    let report = &outcome.report;
    let run = ReportTable::pairs("Run", outcome.header.rows());
    let tables: Vec<&ReportTable> = std::iter::once(&run).chain(&report.tables).collect();
    let mut html = String::new();
    html.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    html.push_str(&format!("<title>{}</title>\n", escape(&report.title)));
    html.push_str(
        "<style>\nbody{font-family:sans-serif;max-width:1050px;margin:2em auto;padding:0 1em;color:#222}\n\
         table{border-collapse:collapse;margin:0.5em 0 1.5em}\n\
         td,th{border:1px solid #ccc;padding:0.25em 0.6em;text-align:left;vertical-align:top}\n\
         th{background:#f0f0f0}\ntd:first-child{font-weight:600}\n\
         figure{margin:1.5em 0}\nfigcaption{color:#555;margin-top:0.3em}\n\
         svg{max-width:100%;height:auto}\n</style>\n</head>\n<body>\n",
    );
    html.push_str(&format!(
        "<h1>{}</h1>\n<p>{}</p>\n",
        escape(&report.title),
        escape(&report.context)
    ));
    for t in &tables {
        html.push_str(&format!("<h2>{}</h2>\n<table>\n", escape(&t.title)));
        if !t.header.is_empty() {
            html.push_str("<tr>");
            for h in &t.header {
                html.push_str(&format!("<th>{}</th>", escape(h)));
            }
            html.push_str("</tr>\n");
        }
        for row in &t.rows {
            html.push_str("<tr>");
            for c in row {
                html.push_str(&format!("<td>{}</td>", escape(c)));
            }
            html.push_str("</tr>\n");
        }
        html.push_str("</table>\n");
    }
    if !outcome.figures.is_empty() {
        html.push_str("<h2>Figures</h2>\n");
    }
    for figure in &outcome.figures {
        let stem = &figure.name;
        if !figures {
            html.push_str(&format!(
                "<p>({stem}: not drawn; set [output] plots = true)</p>\n"
            ));
            continue;
        }
        let path = stage.path(&format!("{stem}.svg"));
        let svg = std::fs::read_to_string(&path)
            .context_with(|| format!("cannot read {}", path.display()))?;
        let svg = svg
            .trim_start()
            .strip_prefix("<?xml")
            .and_then(|rest| rest.split_once("?>").map(|(_, body)| body))
            .unwrap_or(&svg);
        html.push_str("<figure>\n");
        html.push_str(svg.trim());
        html.push_str(&format!(
            "\n<figcaption>{}</figcaption>\n</figure>\n",
            escape(&figure.caption)
        ));
    }
    html.push_str(&format!(
        "<p><small>cps {} · all numbers in SI units · the same figures are in the run's folder as PNG and SVG, the data as CSV and JSON</small></p>\n</body>\n</html>\n",
        env!("CARGO_PKG_VERSION")
    ));
    stage.write("report.html", html.as_bytes())
}
