//! The result model: what a run gives back, as data. Every kind fills the same
//! [`Outcome`] — the run header, summary fields, named tables, named figures, extra
//! documents and the report's text — and [`crate::files`] turns any outcome into a result
//! directory (`summary.json`, one CSV per table, one PNG + SVG per figure,
//! `report.html`) without knowing the kind.

use serde::Serialize;
use serde_json::{Map, Value};

/// How a command that moves a robot, or records from one, ended — for its front end to
/// report (the command line: exit status 0, 1 or 130). Ordered from the best to the
/// worst, so that `max` keeps the worst of two.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Ended {
    /// Done as asked.
    Completed,
    /// Refused, aborted, or the robot or its connection failed (what came is kept).
    Failed,
    /// Stopped on request (Ctrl-C, SIGTERM; what came is kept).
    Stopped,
}

impl Ended {
    /// Completed when `done`, else failed.
    pub fn of(done: bool) -> Ended {
        if done {
            Ended::Completed
        } else {
            Ended::Failed
        }
    }
}

/// The versions that produced a result.
#[derive(Debug, Clone, Serialize)]
pub struct Versions {
    /// The cps version.
    pub cps: &'static str,
    /// The git commit the build comes from (`-dirty` when it had uncommitted changes;
    /// `unknown` outside a git checkout).
    pub commit: &'static str,
}

/// The fields every `summary.json` opens with: which experiment, whether it finished,
/// the seed, the versions, the threads and the wall time.
#[derive(Debug, Clone, Serialize)]
pub struct RunHeader {
    /// The experiment's name.
    pub experiment: String,
    /// Its kind (`viapoint`, `imitation`, …).
    pub kind: &'static str,
    /// False when the run was cancelled or a dependency failed: the results are partial.
    pub complete: bool,
    /// The seed every stochastic part was drawn from.
    pub seed: u64,
    /// The versions that produced the result.
    pub versions: Versions,
    /// Worker threads (the results do not depend on them).
    pub threads: usize,
    /// Wall time of the run, seconds.
    pub wall_time_s: f64,
    /// Why the run stopped early when a dependency failed (a simulator died).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
}

impl RunHeader {
    /// The report's rows for the run itself.
    pub fn rows(&self) -> Vec<(&'static str, String)> {
        vec![
            (
                "experiment",
                format!("{} (kind {})", self.experiment, self.kind),
            ),
            (
                "complete",
                match (&self.failure, self.complete) {
                    (Some(f), _) => format!("no: {f}; the finished part is shown"),
                    (None, true) => "yes".into(),
                    (None, false) => "no: interrupted, the finished part is shown".into(),
                },
            ),
            ("seed", self.seed.to_string()),
            (
                "built from",
                format!(
                    "cps {} (commit {})",
                    self.versions.cps, self.versions.commit
                ),
            ),
            (
                "wall time",
                format!("{:.2} s on {} thread(s)", self.wall_time_s, self.threads),
            ),
        ]
    }
}

/// How the numbers of a column are written as text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Fixed point with this many decimals (`{:.N}`).
    Fixed(usize),
    /// Scientific with this many decimals (`{:.Ne}`).
    Sci(usize),
    /// Scientific, the shortest text that reads back to the same number (`{:e}`).
    ShortestSci,
    /// Plain decimal, the shortest text that reads back to the same number (`{}`).
    Plain,
}

impl Format {
    /// `v` written in this format.
    pub fn write(self, v: f64) -> String {
        match self {
            Format::Fixed(p) => format!("{v:.p$}"),
            Format::Sci(p) => format!("{v:.p$e}"),
            Format::ShortestSci => format!("{v:e}"),
            Format::Plain => format!("{v}"),
        }
    }
}

/// The values of one column.
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    /// Real numbers, written in the column's [`Format`].
    Numbers(Vec<f64>),
    /// Counts and indices.
    Integers(Vec<u64>),
    /// Text (names, lists).
    Texts(Vec<String>),
}

impl Values {
    /// Number of rows.
    pub fn len(&self) -> usize {
        match self {
            Values::Numbers(v) => v.len(),
            Values::Integers(v) => v.len(),
            Values::Texts(v) => v.len(),
        }
    }

    /// True when the column has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One named column of a [`Table`].
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// The header cell.
    pub name: String,
    /// The values, one per row.
    pub values: Values,
    /// How numbers are written.
    pub format: Format,
    /// Write NaN as an empty cell (a value that does not exist for this row).
    pub nan_as_empty: bool,
}

impl Column {
    /// A column of numbers written in `format`.
    pub fn numbers(name: impl Into<String>, values: Vec<f64>, format: Format) -> Self {
        Self {
            name: name.into(),
            values: Values::Numbers(values),
            format,
            nan_as_empty: false,
        }
    }

    /// A column of counts or indices.
    pub fn integers(name: impl Into<String>, values: Vec<u64>) -> Self {
        Self {
            name: name.into(),
            values: Values::Integers(values),
            format: Format::Plain,
            nan_as_empty: false,
        }
    }

    /// A column of text.
    pub fn texts(name: impl Into<String>, values: Vec<String>) -> Self {
        Self {
            name: name.into(),
            values: Values::Texts(values),
            format: Format::Plain,
            nan_as_empty: false,
        }
    }

    /// The same column, NaN written as an empty cell.
    pub fn nan_as_empty(mut self) -> Self {
        self.nan_as_empty = true;
        self
    }

    /// The cell of row `k` as text.
    pub fn cell(&self, k: usize) -> String {
        match &self.values {
            Values::Numbers(v) if self.nan_as_empty && v[k].is_nan() => String::new(),
            Values::Numbers(v) => self.format.write(v[k]),
            Values::Integers(v) => v[k].to_string(),
            Values::Texts(v) => v[k].clone(),
        }
    }
}

/// A named table of columns of equal length; written as `<name>.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// The file stem (`trajectory` → `trajectory.csv`).
    pub name: String,
    /// The columns, left to right.
    pub columns: Vec<Column>,
}

impl Table {
    /// An empty table named `name`.
    pub fn new(name: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            columns: Vec::new(),
        }
    }

    /// Appends a column.
    pub fn with(mut self, column: Column) -> Self {
        self.columns.push(column);
        self
    }

    /// Appends a column in place.
    pub fn push(&mut self, column: Column) {
        self.columns.push(column);
    }

    /// Number of rows (of the first column; [`Table::check`] says whether all agree).
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, |c| c.values.len())
    }

    /// The column named `name`.
    pub fn column(&self, name: &str) -> Option<&Column> {
        self.columns.iter().find(|c| c.name == name)
    }

    /// Whether every column has the same number of rows (the sentence says which not).
    pub fn check(&self) -> Result<(), String> {
        let n = self.rows();
        match self.columns.iter().find(|c| c.values.len() != n) {
            Some(c) => Err(format!(
                "table {}: column {} has {} rows, the first has {n}",
                self.name,
                c.name,
                c.values.len()
            )),
            None => Ok(()),
        }
    }
}

/// A curve family of a figure: one line per dimension over time.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend label (empty: no legend entry; faint series with one label share it).
    pub label: String,
    /// Time stamps, seconds.
    pub times: Vec<f64>,
    /// `values[d][k]`: dimension d at `times[k]`.
    pub values: Vec<Vec<f64>>,
    /// Drawn thin and light (for many recordings or bands) instead of bold.
    pub faint: bool,
}

impl Series {
    /// A bold, labelled series.
    pub fn new(label: impl Into<String>, times: Vec<f64>, values: Vec<Vec<f64>>) -> Self {
        Self {
            label: label.into(),
            times,
            values,
            faint: false,
        }
    }

    /// The same series, drawn faint.
    pub fn faint(mut self) -> Self {
        self.faint = true;
        self
    }
}

/// One curve family of a cost figure: the mean best-so-far cost per generation and its
/// 95 % band over repetitions.
#[derive(Debug, Clone, PartialEq)]
pub struct CostArm {
    /// Legend label.
    pub label: String,
    /// Repetitions behind the band (1: no band is drawn).
    pub repetitions: usize,
    /// Per generation: (mean, lower, upper) of the best cost so far.
    pub band: Vec<(f64, f64, f64)>,
    /// The smallest and largest positive finite best-so-far cost of any repetition
    /// (`(inf, 0)` when there is none): the figure's range.
    pub range: (f64, f64),
}

/// What a marked point is, which decides how it is drawn and labelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MarkKind {
    /// Where the movement starts.
    Start,
    /// A via point (labelled `p1`, `p2`, …).
    Via,
    /// Where it ends.
    Goal,
    /// A point obstacle (drawn in 3-D paths; labelled `o1`, `o2`, …).
    Obstacle,
    /// Where a motion-capture marker's filled gap begins (a hollow circle).
    Gap,
}

/// A marked point of a figure: a way point, or a target at a time.
#[derive(Debug, Clone, PartialEq)]
pub struct Mark {
    /// Its time, seconds (ignored in 3-D paths).
    pub time: f64,
    /// One value per panel (x, y, z in 3-D paths).
    pub values: Vec<f64>,
    /// Start, via point or goal.
    pub kind: MarkKind,
    /// Its label (`start`, `p1`, `goal`).
    pub label: String,
}

/// A shaded band between two curves per panel (a 95 % band, mean ± 2σ).
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    /// Legend label.
    pub label: String,
    /// Time stamps.
    pub times: Vec<f64>,
    /// `lower[d][k]` and `upper[d][k]` per panel d.
    pub lower: Vec<Vec<f64>>,
    /// Upper edge.
    pub upper: Vec<Vec<f64>>,
}

/// One panel per dimension over a shared horizontal axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Panels {
    /// The horizontal axis's name with its unit (`t [s]`, `generation`).
    pub x_name: String,
    /// Each panel's vertical axis name with its unit.
    pub names: Vec<String>,
    /// The curves; each has one value row per panel (NaN: not in that panel).
    pub series: Vec<Series>,
    /// Shaded bands, drawn under the curves.
    pub bands: Vec<Band>,
    /// Marked points.
    pub marks: Vec<Mark>,
    /// Per panel, limits drawn as lines with the outside shaded.
    pub limits: Vec<Option<(f64, f64)>>,
    /// Logarithmic vertical axes.
    pub log_y: bool,
}

impl Panels {
    /// Panels named `names` over time (`t [s]`) with `series`.
    pub fn new(names: Vec<String>, series: Vec<Series>) -> Self {
        Self {
            x_name: "t [s]".into(),
            names,
            series,
            bands: Vec::new(),
            marks: Vec::new(),
            limits: Vec::new(),
            log_y: false,
        }
    }

    /// With marked points.
    pub fn marks(mut self, marks: Vec<Mark>) -> Self {
        self.marks = marks;
        self
    }

    /// With shaded bands.
    pub fn bands(mut self, bands: Vec<Band>) -> Self {
        self.bands = bands;
        self
    }

    /// With per-panel limits.
    pub fn limits(mut self, limits: Vec<Option<(f64, f64)>>) -> Self {
        self.limits = limits;
        self
    }
}

/// What a figure shows.
#[derive(Debug, Clone, PartialEq)]
pub enum Plot {
    /// Best cost so far per generation (log scale), per arm, with the exact optimum.
    Cost {
        /// The curve families.
        arms: Vec<CostArm>,
        /// The exact optimum's cost, drawn as a line, when there is one.
        optimum: Option<f64>,
    },
    /// One panel per dimension.
    Panels(Panels),
    /// A 3-D path (world frame, z up) of every three-dimensional series, marked points.
    Path3d {
        /// The paths (`values` has x, y, z).
        series: Vec<Series>,
        /// Marked positions.
        marks: Vec<Mark>,
    },
}

/// A named figure; written as `<name>.png` and `<name>.svg`, shown in the report with its
/// caption.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// The file stem.
    pub name: String,
    /// The report's caption.
    pub caption: String,
    /// What it shows.
    pub plot: Plot,
}

/// A titled table of the report (text cells).
#[derive(Debug, Clone, PartialEq)]
pub struct ReportTable {
    /// Heading above the table.
    pub title: String,
    /// Column headings (empty: a key/value table without headings).
    pub header: Vec<String>,
    /// Rows of cells.
    pub rows: Vec<Vec<String>>,
}

impl ReportTable {
    /// A key/value table.
    pub fn pairs(title: &str, rows: Vec<(&str, String)>) -> Self {
        Self {
            title: title.into(),
            header: Vec::new(),
            rows: rows.into_iter().map(|(k, v)| vec![k.into(), v]).collect(),
        }
    }
}

/// The report's words: a title, a line of context and its tables (the run's own table and
/// the figures are added by the writer).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Report {
    /// The page title.
    pub title: String,
    /// One paragraph saying what was done.
    pub context: String,
    /// Result tables.
    pub tables: Vec<ReportTable>,
}

/// A file of the result that is neither a table nor a figure (a learned model, an
/// exported trajectory).
#[derive(Debug, Clone, PartialEq)]
pub struct Document {
    /// The file name.
    pub name: String,
    /// Its content.
    pub bytes: Vec<u8>,
}

impl Document {
    /// A text file.
    pub fn text(name: impl Into<String>, text: String) -> Self {
        Document {
            name: name.into(),
            bytes: text.into_bytes(),
        }
    }
}

/// Everything a run gives back. Writing it ([`crate::files`]) is the same for every kind.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The run itself: experiment, kind, completeness, seed, versions, threads, wall time.
    pub header: RunHeader,
    /// The kind's summary fields, in order (`summary.json` is the header, then these).
    pub summary: Map<String, Value>,
    /// Named tables (`<name>.csv`).
    pub tables: Vec<Table>,
    /// Named figures (`<name>.png`, `<name>.svg`), in the report's order.
    pub figures: Vec<Figure>,
    /// Other files (learned models).
    pub documents: Vec<Document>,
    /// The report's words.
    pub report: Report,
    /// A few lines saying what came out, for a terminal or a notebook.
    pub lines: Vec<String>,
}

impl Outcome {
    /// Whether the run finished (not cancelled, no dependency failed).
    pub fn complete(&self) -> bool {
        self.header.complete
    }

    /// Why the run stopped early, when a dependency failed.
    pub fn failure(&self) -> Option<&str> {
        self.header.failure.as_deref()
    }

    /// The table named `name`.
    pub fn table(&self, name: &str) -> Option<&Table> {
        self.tables.iter().find(|t| t.name == name)
    }

    /// The figure named `name`.
    pub fn figure(&self, name: &str) -> Option<&Figure> {
        self.figures.iter().find(|f| f.name == name)
    }

    /// `summary.json`'s content: the header's fields, then the kind's.
    pub fn summary_json(&self) -> Value {
        let mut all = match serde_json::to_value(&self.header) {
            Ok(Value::Object(m)) => m,
            _ => Map::new(),
        };
        all.extend(self.summary.iter().map(|(k, v)| (k.clone(), v.clone())));
        Value::Object(all)
    }
}

/// A kind's typed summary as ordered fields (its `Serialize` field order is kept).
pub fn fields(summary: &impl Serialize) -> Map<String, Value> {
    match serde_json::to_value(summary) {
        Ok(Value::Object(m)) => m,
        // A summary struct always serialises to an object; anything else is kept whole.
        Ok(other) => Map::from_iter([("summary".to_string(), other)]),
        Err(e) => Map::from_iter([("summary_error".to_string(), Value::String(e.to_string()))]),
    }
}
