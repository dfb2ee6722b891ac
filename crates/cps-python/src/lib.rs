//! The Python package `cps` (this crate is its extension module `cps._cps`): DMPs,
//! CMA-ES with pycma's interface, via-point learning, every experiment kind and robot
//! kinematics, with numpy arrays in and out. Built by maturin from `python/pyproject.toml`
//! (`pip install ./python`); the Python sources, stubs and tests are in `python/`.
//!
//! Every function translates Python objects into calls of the Rust crates and back — no
//! pipeline logic lives here. Long work runs with the GIL released and stops cleanly on
//! Ctrl-C (`interrupt.rs`); bad input raises `ValueError` with the sentence the command
//! line prints, naming the argument (`errors.rs`, `arrays.rs`).
//!
//! ```python
//! import numpy as np, cps
//! t = np.linspace(0.0, 1.0, 101)
//! y = np.column_stack([np.sin(t), t**2])
//! dmp = cps.imitate(t, y, bases=25)
//! t2, pos, vel, acc = dmp.rollout(goal=[1.0, 2.0])
//! es = cps.CMAES(np.zeros(10), 0.5, {"seed": 3})
//! while not es.stop():
//!     X = es.ask()
//!     es.tell(X, (X**2).sum(axis=1))
//! ```
#![deny(missing_docs)]

mod arrays;
mod chunks;
mod cmaes;
mod dmp;
mod errors;
mod experiment;
mod franka;
mod interrupt;
mod kinematics;
mod learn;
mod lerobot;
mod mocap;
mod promp;
mod ros2;

use pyo3::prelude::*;

/// The extension module `cps._cps`; `cps/__init__.py` re-exports it.
#[pymodule]
fn _cps(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("CpsError", py.get_type::<errors::CpsError>())?;
    m.add_class::<dmp::Dmp>()?;
    m.add_class::<dmp::Trajectory>()?;
    m.add_class::<dmp::Stepper>()?;
    m.add_class::<dmp::Rhythmic>()?;
    m.add_class::<dmp::Orientation>()?;
    m.add_function(wrap_pyfunction!(dmp::imitate, m)?)?;
    m.add_function(wrap_pyfunction!(dmp::sequence, m)?)?;
    m.add_class::<cmaes::Es>()?;
    m.add_function(wrap_pyfunction!(cmaes::_fmin, m)?)?;
    m.add_class::<learn::ViaPointResult>()?;
    m.add_function(wrap_pyfunction!(learn::learn_via_points, m)?)?;
    m.add_class::<experiment::Outcome>()?;
    m.add_class::<experiment::Table>()?;
    m.add_function(wrap_pyfunction!(experiment::run_experiment, m)?)?;
    m.add_class::<kinematics::Robot>()?;
    m.add_class::<franka::Franka>()?;
    m.add_class::<chunks::ChunkExecutor>()?;
    m.add_function(wrap_pyfunction!(chunks::chunk_commands, m)?)?;
    m.add_function(wrap_pyfunction!(franka::identify, m)?)?;
    m.add_function(wrap_pyfunction!(mocap::_mocap_take, m)?)?;
    m.add_function(wrap_pyfunction!(lerobot::_lerobot_show, m)?)?;
    m.add_function(wrap_pyfunction!(lerobot::_lerobot_demos, m)?)?;
    m.add_function(wrap_pyfunction!(lerobot::_lerobot_write, m)?)?;
    m.add_function(wrap_pyfunction!(lerobot::_lerobot_write_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(mocap::_mocap_read, m)?)?;
    m.add_function(wrap_pyfunction!(ros2::_ros2_send, m)?)?;
    m.add_function(wrap_pyfunction!(ros2::_ros2_record, m)?)?;
    m.add_function(wrap_pyfunction!(ros2::_ros2_graph, m)?)?;
    m.add_class::<promp::PyProMp>()?;
    Ok(())
}
