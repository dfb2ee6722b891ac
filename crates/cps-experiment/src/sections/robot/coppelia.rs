//! `[robot] backend = "coppelia"`: CoppeliaSim (or `cps-cli sim serve`) over the ZMQ
//! remote API — its endpoint (or a pool of simulators), the robot's alias, timeout, who
//! moves the joints.

use std::time::Duration;

use toml::Spanned;

use super::{BackendChoice, Control, RobotSection};
use crate::InputError;
use crate::sections::{Kind, Sections};

/// The keys only this backend reads (`name` is named without its place).
pub(super) fn keys(r: &RobotSection) -> super::Keys {
    vec![
        ("endpoint", r.endpoint.as_ref().map(Spanned::span)),
        ("endpoints", r.endpoints.as_ref().map(Spanned::span)),
        ("name", None),
        ("timeout", r.timeout.as_ref().map(Spanned::span)),
        ("control", r.control.as_ref().map(Spanned::span)),
    ]
}

impl Sections<'_> {
    /// An endpoint `tcp://host:port` with a port from 1 to 65535; `what` names it.
    pub(super) fn endpoint(&self, e: &Spanned<String>, what: &str) -> Result<String, InputError> {
        let text = e.get_ref();
        let port = text
            .strip_prefix("tcp://")
            .and_then(|rest| rest.rsplit_once(':'))
            .filter(|(host, _)| !host.is_empty())
            .and_then(|(_, p)| p.parse::<u16>().ok());
        if port.is_none_or(|p| p == 0) {
            return Err(self.err(
                &e.span(),
                format!(
                    "[robot] {what} must look like tcp://host:port with a port from 1 to 65535 (got `{text}`)"
                ),
            ));
        }
        Ok(text.clone())
    }

    /// `[robot] endpoints`: a pool of simulators, for `kind = "viapoint_executed"` only,
    /// not beside `endpoint`, at least one, each once (`localhost` is `127.0.0.1`); without
    /// it, the pool is `endpoint` alone.
    pub(super) fn pool_endpoints(
        &self,
        section: Option<&RobotSection>,
        endpoint: &str,
    ) -> Result<Vec<String>, InputError> {
        let Some(list) = section.and_then(|r| r.endpoints.as_ref()) else {
            return Ok(vec![endpoint.to_string()]);
        };
        if self.kind != Kind::ViapointExecuted {
            return Err(self.err(
                &list.span(),
                format!(
                    "[robot] `endpoints` (a pool of simulators) is read only by kind = \"viapoint_executed\"; kind = \"{}\" executes on one: use `endpoint`",
                    self.kind.name()
                ),
            ));
        }
        if section.is_some_and(|r| r.endpoint.is_some()) {
            return Err(self.err(
                &list.span(),
                "[robot] give either `endpoint` (one simulator) or `endpoints` (a pool), not both"
                    .into(),
            ));
        }
        if list.get_ref().is_empty() || list.get_ref().len() > 256 {
            return Err(self.err(
                &list.span(),
                format!(
                    "[robot] `endpoints` must name 1 to 256 simulators (got {})",
                    list.get_ref().len()
                ),
            ));
        }
        let mut seen: Vec<(String, usize)> = Vec::new();
        let mut pool = Vec::new();
        for (i, e) in list.get_ref().iter().enumerate() {
            let text = self.endpoint(e, &format!("`endpoints[{i}]`"))?;
            let key = text.replacen("tcp://localhost:", "tcp://127.0.0.1:", 1);
            if let Some((_, j)) = seen.iter().find(|(k, _)| *k == key) {
                return Err(self.err(
                    &e.span(),
                    format!(
                        "[robot] `endpoints[{i}]` and `endpoints[{j}]` name the same simulator ({text}): each simulator runs one candidate at a time, list it once"
                    ),
                ));
            }
            seen.push((key, i));
            pool.push(text);
        }
        Ok(pool)
    }

    /// `[robot] backend = "coppelia"`: `endpoint` or `endpoints`, `name`, `timeout`,
    /// `control`, `dt` (checked against the simulator's step when it is reached).
    pub(super) fn coppelia_choice(
        &self,
        section: Option<&RobotSection>,
    ) -> Result<BackendChoice, InputError> {
        if let Some(c) = section.and_then(|r| r.control.as_ref())
            && *c.get_ref() == Control::SimulatorIk
            && self.kind == Kind::ViapointJoint
        {
            return Err(self.err(
                    &c.span(),
                    "[robot] control = \"simulator_ik\" executes tool targets; a joint-space experiment commands the joints itself (use control = \"cps\")".into(),
                ));
        }
        if let Some(c) = section.and_then(|r| r.control.as_ref())
            && *c.get_ref() == Control::SimulatorIk
            && self.kind == Kind::ViapointExecuted
        {
            return Err(self.err(
                    &c.span(),
                    "[robot] control = \"simulator_ik\" moves the IK target one step at a time; learning on the executed cost sends whole joint sequences to the scene script (use control = \"cps\")".into(),
                ));
        }
        // A `dt` is the control period the file expects: checked against the
        // simulator's time step when it is reached.
        let expected_dt = match section.and_then(|r| r.dt.as_ref()) {
            Some(d) => Some(self.within(d, "[robot] `dt`", 1e-4, 1.0, " s")?),
            None => None,
        };
        let endpoint = match section.and_then(|r| r.endpoint.as_ref()) {
            None => "tcp://127.0.0.1:23000".to_string(),
            Some(e) => self.endpoint(e, "`endpoint`")?,
        };
        let pool = self.pool_endpoints(section, &endpoint)?;
        let timeout = match section.and_then(|r| r.timeout.as_ref()) {
            Some(t) => self.within(t, "[robot] `timeout`", 0.01, 3600.0, " s")?,
            None => 5.0,
        };
        Ok(BackendChoice::Coppelia {
            endpoint: pool[0].clone(),
            pool,
            robot_name: section
                .and_then(|r| r.name.clone())
                .unwrap_or_else(|| "Panda".into()),
            timeout: Duration::from_secs_f64(timeout),
            simulator_ik: section
                .and_then(|r| r.control.as_ref())
                .is_some_and(|c| *c.get_ref() == Control::SimulatorIk),
            expected_dt,
        })
    }
}
