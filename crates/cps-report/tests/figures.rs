//! The figures: degenerate data never panics the drawing; tick labels read as numbers.
//! (All of cps-report's tests are here: the library is not compiled a second time for
//! unit tests.)
#![cfg(feature = "figures")]

use cps_outcome::outcome::{Band, CostArm, Figure, Mark, MarkKind, Panels, Plot, Series};
use cps_report::figures::{draw, log_tick, tick};

fn series(times: Vec<f64>, values: Vec<Vec<f64>>) -> Series {
    Series::new("s", times, values)
}

/// Degenerate data never panics the drawing: empty, single-sample, constant, NaN,
/// infinite, huge and non-positive (log) values, in every kind of plot.
#[test]
fn degenerate_data_draws_without_panicking() {
    let odd: Vec<Vec<f64>> = vec![
        vec![],
        vec![1.0],
        vec![2.0, 2.0, 2.0],
        vec![f64::NAN, 1.0, f64::NAN],
        vec![f64::INFINITY, -1e300, 0.0],
        vec![0.0, -1.0, 1e-320],
    ];
    let dir = tempfile::tempdir().unwrap();
    let mut k = 0;
    for v in &odd {
        let times: Vec<f64> = (0..v.len()).map(|i| i as f64).collect();
        let s = series(times.clone(), vec![v.clone(), v.clone(), v.clone()]);
        let mark = Mark {
            time: f64::NAN,
            values: v.clone(),
            kind: MarkKind::Via,
            label: "p1".into(),
        };
        let mut panels = Panels::new(vec!["a".into(), "b".into(), "c".into()], vec![s.clone()])
            .marks(vec![mark.clone()])
            .bands(vec![Band {
                label: "band".into(),
                times: times.clone(),
                lower: vec![v.clone(); 3],
                upper: vec![v.clone(); 3],
            }])
            .limits(vec![Some((1.0, 1.0)), None, Some((f64::NAN, 0.0))]);
        let mut plots = vec![
            Plot::Panels(panels.clone()),
            Plot::Path3d {
                series: vec![s.clone()],
                marks: vec![mark],
            },
            Plot::Cost {
                arms: vec![CostArm {
                    label: "arm".into(),
                    repetitions: 2,
                    band: v.iter().map(|&x| (x, x, x)).collect(),
                    range: (f64::INFINITY, 0.0),
                }],
                optimum: v.first().copied(),
            },
        ];
        panels.log_y = true;
        plots.push(Plot::Panels(panels));
        for plot in plots {
            let figure = Figure {
                name: "f".into(),
                caption: String::new(),
                plot,
            };
            for ext in ["png", "svg"] {
                k += 1;
                // An error is acceptable for nonsense; a panic is not.
                let _ = draw(&figure, &dir.path().join(format!("f{k}.{ext}")));
            }
        }
    }
}

#[test]
fn ticks_read_as_numbers() {
    let f = tick(1.0);
    assert_eq!(f(&0.5), "0.5");
    assert_eq!(f(&-1.1e-16), "0");
    assert_eq!(f(&-0.0), "0");
    assert_eq!(tick(400_000.0)(&100_000.0), "1e5");
    assert_eq!(tick(10.0)(&3.0), "3");
    assert_eq!(log_tick(&4.0), "1e4");
    assert_eq!(log_tick(&-1.0), "0.1");
    assert_eq!(log_tick(&3.5), "3.2e3");
}
