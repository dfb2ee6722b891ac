//! `[robot] backend = "franka"`: a Franka over the Franka Control Interface — its host
//! (or a pool of hosts), arm, realtime scheduling and control period.

use toml::Spanned;

use super::{BackendChoice, RobotSection};
use crate::InputError;
use crate::sections::{Kind, Sections};

/// The keys only this backend reads.
pub(super) fn keys(r: &RobotSection) -> super::Keys {
    vec![
        ("host", r.host.as_ref().map(Spanned::span)),
        ("hosts", r.hosts.as_ref().map(Spanned::span)),
        ("arm", r.arm.as_ref().map(Spanned::span)),
        ("realtime", r.realtime.as_ref().map(Spanned::span)),
    ]
}

impl Sections<'_> {
    /// `[robot] backend = "franka"`: `host` or `hosts`, `arm`, `realtime`, `dt`.
    pub(super) fn franka_choice(
        &self,
        section: Option<&RobotSection>,
        model: &str,
        default_dt: f64,
    ) -> Result<BackendChoice, InputError> {
        use cps_franka::limits::Arm;
        let Some(r) = section else {
            unreachable!("backend = \"franka\" is read from a [robot] section")
        };
        let check_host = |h: &Spanned<String>, what: &str| -> Result<String, InputError> {
            let text = h.get_ref().trim();
            let ok = !text.is_empty()
                && !text.contains("://")
                && !text.contains(char::is_whitespace)
                && text.rsplit_once(':').is_none_or(|(host, p)| {
                    !host.is_empty() && p.parse::<u16>().is_ok_and(|p| p > 0)
                });
            if ok {
                Ok(text.to_string())
            } else {
                Err(self.err(
                    &h.span(),
                    format!(
                        "[robot] {what} must be the robot's address, `ip` or `ip:port` (got `{}`)",
                        h.get_ref()
                    ),
                ))
            }
        };
        let pool = match (&r.host, &r.hosts) {
            (Some(_), Some(list)) => {
                return Err(self.err(
                    &list.span(),
                    "[robot] give either `host` (one robot) or `hosts` (a pool), not both".into(),
                ));
            }
            (None, None) => {
                return Err(InputError(format!(
                    "{}: [robot] backend = \"franka\" needs `host`, the robot's address (e.g. host = \"172.16.0.2\"): cps never guesses which robot to move",
                    self.path.display()
                )));
            }
            (Some(h), None) => vec![check_host(h, "`host`")?],
            (None, Some(list)) => {
                if self.kind != Kind::ViapointExecuted {
                    return Err(self.err(
                        &list.span(),
                        format!(
                            "[robot] `hosts` (a pool of robots) is read only by kind = \"viapoint_executed\"; kind = \"{}\" executes on one: use `host`",
                            self.kind.name()
                        ),
                    ));
                }
                if list.get_ref().is_empty() || list.get_ref().len() > 64 {
                    return Err(self.err(
                        &list.span(),
                        format!(
                            "[robot] `hosts` must name 1 to 64 robots (got {})",
                            list.get_ref().len()
                        ),
                    ));
                }
                let mut pool: Vec<String> = Vec::new();
                for (i, h) in list.get_ref().iter().enumerate() {
                    let text = check_host(h, &format!("`hosts[{i}]`"))?;
                    if let Some(j) = pool.iter().position(|p| *p == text) {
                        return Err(self.err(
                            &h.span(),
                            format!("[robot] `hosts[{i}]` and `hosts[{j}]` name the same robot ({text}): list it once"),
                        ));
                    }
                    pool.push(text);
                }
                pool
            }
        };
        let arm = match &r.arm {
            Some(a) => Arm::from_name(a.get_ref()).ok_or_else(|| {
                self.err(
                    &a.span(),
                    format!("[robot] `arm` must be fr3 or panda (got `{}`)", a.get_ref()),
                )
            })?,
            None => Arm::from_name(model).ok_or_else(|| {
                InputError(format!(
                    "{}: [robot] the scene's robot `{model}` is not a Franka arm: set `arm = \"fr3\"` or `\"panda\"` to say whose limits the commands must keep",
                    self.path.display()
                ))
            })?,
        };
        let realtime = match &r.realtime {
            Some(m) => cps_drive::franka::parse_realtime(m.get_ref()).map_err(|_| {
                self.err(
                    &m.span(),
                    format!(
                        "[robot] `realtime` must be enforce, ignore or off (got `{}`)",
                        m.get_ref()
                    ),
                )
            })?,
            None => cps_franka::Realtime::Enforce,
        };
        let dt = match r.dt.as_ref() {
            Some(d) => {
                let dt = self.within(d, "[robot] `dt`", 1e-3, 1.0, " s")?;
                if ((dt * 1e3).round() - dt * 1e3).abs() > 1e-6 {
                    return Err(self.err(
                        &d.span(),
                        format!("[robot] `dt` must be a whole number of milliseconds with backend = \"franka\" (the robot takes a command every millisecond; got {dt} s)"),
                    ));
                }
                dt
            }
            None if ((default_dt * 1e3).round() - default_dt * 1e3).abs() > 1e-6
                || default_dt < 1e-3 =>
            {
                return Err(InputError(format!(
                    "{}: the movement is planned every {default_dt} s, not a whole number of milliseconds: set [robot] dt (e.g. 0.01) for the Franka",
                    self.path.display()
                )));
            }
            None => default_dt,
        };
        Ok(BackendChoice::Franka {
            host: pool[0].clone(),
            pool,
            arm,
            realtime,
            dt,
        })
    }
}
