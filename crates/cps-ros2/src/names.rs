//! ROS 2 names and their DDS spellings (rmw's conventions): a node's name, namespace and
//! domain; topics as `rt/` + the fully qualified name without its leading slash; a
//! service's request and reply topics as `rq/<name>Request` and `rr/<name>Reply`; an
//! action as three services and two topics under `<name>/_action/`.

use crate::Ros2Error;

/// The DDS domain ROS 2 uses unless `ROS_DOMAIN_ID` says otherwise.
pub const DEFAULT_DOMAIN: u16 = 0;

/// The largest domain id whose ports fit in 16 bits (RTPS: 7400 + 250 × domain + …).
pub const MAX_DOMAIN: u16 = 232;

/// A node's identity on the graph.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeName {
    /// The DDS domain (ROS_DOMAIN_ID).
    pub domain: u16,
    /// The namespace, `/` or `/a/b`.
    pub namespace: String,
    /// The node's name, one token.
    pub name: String,
}

impl NodeName {
    /// A node `name` in `namespace` on `domain`; each checked as ROS 2 checks them.
    pub fn new(name: &str, namespace: &str, domain: u16) -> Result<Self, Ros2Error> {
        check_token(name, "node name")?;
        let namespace = if namespace.is_empty() { "/" } else { namespace };
        if !namespace.starts_with('/') {
            return Err(Ros2Error::Input(format!(
                "namespace `{namespace}`: a namespace starts with `/`"
            )));
        }
        if namespace != "/" {
            check_name(namespace, "namespace")?;
        }
        check_domain(domain)?;
        Ok(NodeName {
            domain,
            namespace: namespace.to_string(),
            name: name.to_string(),
        })
    }

    /// `name` in the root namespace, on `domain` or else on `ROS_DOMAIN_ID`'s (unset or
    /// empty: 0).
    pub fn from_env(name: &str, domain: Option<u16>) -> Result<Self, Ros2Error> {
        let domain = match domain {
            Some(d) => d,
            None => domain_from_env(std::env::var("ROS_DOMAIN_ID").ok().as_deref())?,
        };
        Self::new(name, "/", domain)
    }

    /// The node's fully qualified name (`/ns/name`).
    pub fn fully_qualified(&self) -> String {
        join(&self.namespace, &self.name)
    }
}

/// The domain `ROS_DOMAIN_ID` gives (`None` or empty: the default).
pub fn domain_from_env(value: Option<&str>) -> Result<u16, Ros2Error> {
    match value.map(str::trim) {
        None | Some("") => Ok(DEFAULT_DOMAIN),
        Some(v) => {
            let d = v.parse::<u16>().map_err(|_| {
                Ros2Error::Input(format!(
                    "ROS_DOMAIN_ID={v}: give a whole number from 0 to {MAX_DOMAIN}"
                ))
            })?;
            check_domain(d)?;
            Ok(d)
        }
    }
}

/// A domain as a user writes it (`--domain 7`): a whole number from 0 to [`MAX_DOMAIN`],
/// or a sentence stating that range.
pub fn parse_domain(s: &str) -> Result<u16, String> {
    s.trim()
        .parse::<u16>()
        .ok()
        .filter(|d| *d <= MAX_DOMAIN)
        .ok_or_else(|| {
            format!(
                "domain {s}: give a DDS domain, a whole number from 0 to {MAX_DOMAIN} (their ports must fit in 16 bits)"
            )
        })
}

fn check_domain(d: u16) -> Result<(), Ros2Error> {
    if d > MAX_DOMAIN {
        return Err(Ros2Error::Input(format!(
            "domain {d}: DDS domains run from 0 to {MAX_DOMAIN} (their ports must fit in 16 bits)"
        )));
    }
    Ok(())
}

fn join(namespace: &str, name: &str) -> String {
    if namespace == "/" {
        format!("/{name}")
    } else {
        format!("{namespace}/{name}")
    }
}

fn check_token(t: &str, what: &str) -> Result<(), Ros2Error> {
    let ok = !t.is_empty()
        && !t.starts_with(|c: char| c.is_ascii_digit())
        && t.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !t.contains("__");
    if ok {
        Ok(())
    } else {
        Err(Ros2Error::Input(format!(
            "{what} `{t}`: ROS names are letters, digits and single underscores, not starting with a digit"
        )))
    }
}

fn check_name(n: &str, what: &str) -> Result<(), Ros2Error> {
    let body = n.strip_prefix('/').unwrap_or(n);
    if body.is_empty() || body.ends_with('/') {
        return Err(Ros2Error::Input(format!(
            "{what} `{n}`: a name is tokens joined by `/`, with no empty token or trailing `/`"
        )));
    }
    for t in body.split('/') {
        check_token(t, what).map_err(|_| {
            Ros2Error::Input(format!(
                "{what} `{n}`: its part `{t}` is not a ROS name (letters, digits and single underscores, not starting with a digit)"
            ))
        })?;
    }
    Ok(())
}

/// A topic, service or action name as ROS resolves it for `node`: absolute (`/a/b`),
/// private (`~/b`, under the node's own name) or relative (in the node's namespace).
pub fn resolve(node: &NodeName, name: &str) -> Result<String, Ros2Error> {
    let full = if let Some(rest) = name.strip_prefix("~/") {
        join(&node.fully_qualified(), rest)
    } else if name.starts_with('/') {
        name.to_string()
    } else {
        join(&node.namespace, name)
    };
    check_name(&full, "name")?;
    Ok(full)
}

/// A topic's DDS name: `rt/` and the resolved name without its leading slash.
pub fn dds_topic(node: &NodeName, name: &str) -> Result<String, Ros2Error> {
    Ok(format!("rt{}", resolve(node, name)?))
}

/// A service's request and reply topics.
pub fn dds_service(node: &NodeName, name: &str) -> Result<(String, String), Ros2Error> {
    let full = resolve(node, name)?;
    Ok((format!("rq{full}Request"), format!("rr{full}Reply")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_as_rcl_resolves_them() {
        let n = NodeName::new("cps", "/lab", 0).unwrap();
        assert_eq!(n.fully_qualified(), "/lab/cps");
        assert_eq!(dds_topic(&n, "/joint_states").unwrap(), "rt/joint_states");
        assert_eq!(
            dds_topic(&n, "joint_states").unwrap(),
            "rt/lab/joint_states"
        );
        assert_eq!(dds_topic(&n, "~/markers").unwrap(), "rt/lab/cps/markers");
        assert_eq!(
            dds_service(&n, "/arm/follow_joint_trajectory/_action/send_goal").unwrap(),
            (
                "rq/arm/follow_joint_trajectory/_action/send_goalRequest".into(),
                "rr/arm/follow_joint_trajectory/_action/send_goalReply".into()
            )
        );
        let root = NodeName::new("cps", "", 3).unwrap();
        assert_eq!(root.fully_qualified(), "/cps");
        assert_eq!(dds_topic(&root, "a/b").unwrap(), "rt/a/b");
    }

    #[test]
    fn bad_names_and_domains_are_named() {
        for bad in ["", "/", "/a//b", "/a/", "/1a", "/a b", "/a__b"] {
            let e = dds_topic(&NodeName::new("cps", "/", 0).unwrap(), bad).unwrap_err();
            assert!(e.to_string().contains("name"), "{bad}: {e}");
        }
        assert!(NodeName::new("c-ps", "/", 0).is_err());
        assert!(NodeName::new("cps", "lab", 0).is_err());
        assert!(NodeName::new("cps", "/", 233).is_err());
        assert_eq!(domain_from_env(None).unwrap(), 0);
        assert_eq!(domain_from_env(Some(" 42 ")).unwrap(), 42);
        let e = domain_from_env(Some("x")).unwrap_err().to_string();
        assert!(e.contains("ROS_DOMAIN_ID=x"), "{e}");
        assert!(domain_from_env(Some("300")).is_err());
    }
}
