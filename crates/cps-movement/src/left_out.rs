//! The pairs of links a robot's description leaves out of the collision checks, verified
//! on the shapes cps checks rather than trusted.
//!
//! An SRDF's `reason="Never"` comes from its author's sampling on the meshes they had
//! (MoveIt's setup assistant), not from a proof. Each pair it leaves out is searched over
//! the joint ranges ([`cps_robot::closest_approaches`]) and kept with the closest approach
//! found ([`cps_robot::Why::Searched`]): the guard leaves it out only while it stays
//! farther apart than the margin, and checks it otherwise. The built-in Franka arms carry
//! the search's results ([`FRANKA_LEFT_OUT`], the same search run by
//! `tests/collision_mujoco.rs`); a URDF's SRDF is searched once and the result cached
//! beside it (`ROBOT.pairs.json`, keyed by a hash of everything the search depends on).

use std::path::Path;

use cps_geometry::{Body, Shape};
use cps_kinematics::SerialChain;
use cps_robot::{LeftOut, NeverSearch, Why};
use serde::{Deserialize, Serialize};

/// franka_description's SRDF pairs (franka_arm.srdf.xacro, franka_hand.srdf.xacro) beyond
/// those a joint joins, without the arm's prefix, each with the closest approach cps's
/// search ([`NeverSearch::default`]) finds over the arm's joint ranges on the FR3's and
/// the Panda's hulls (m, negative: inside each other), the fingers open
/// ([`crate::collision::FINGER_OPENING`]). link2–link6 and link5–link7 meet on both
/// arms: they are checked. The hand's pairs hold when the model has the hand; a finger
/// and link7, and the two fingers, ride on one frame (the fingers held open): they never
/// move relative to each other ([`Why::Fixed`]).
pub const FRANKA_LEFT_OUT: [(&str, &str, f64, f64); 25] = [
    // (first, second, closest on the FR3, on the Panda); INF: on one frame (fixed).
    ("link0", "link2", 0.1212, 0.1239),
    ("link0", "link3", 0.1377, 0.1461),
    ("link0", "link4", 0.0267, 0.0321),
    ("link1", "link3", 0.1217, 0.1258),
    ("link1", "link4", 0.1054, 0.1067),
    ("link2", "link4", 0.0488, 0.0472),
    ("link2", "link6", -0.0474, -0.0587),
    ("link3", "link5", 0.0501, 0.0503),
    ("link3", "link6", 0.1531, 0.1535),
    ("link3", "link7", 0.1079, 0.1563),
    ("link4", "link6", 0.1212, 0.1363),
    ("link4", "link7", 0.1145, 0.1522),
    ("link5", "link7", -0.0097, -0.0529),
    ("hand", "link3", 0.0969, 0.0901),
    ("hand", "link4", 0.1128, 0.0860),
    ("hand", "link6", 0.0298, 0.0297),
    ("leftfinger", "link3", 0.0940, 0.0432),
    ("leftfinger", "link4", 0.1227, 0.0392),
    ("leftfinger", "link6", 0.1144, 0.1143),
    ("leftfinger", "link7", INF, INF),
    ("rightfinger", "link3", 0.0940, 0.0432),
    ("rightfinger", "link4", 0.1228, 0.0392),
    ("rightfinger", "link6", 0.1144, 0.1143),
    ("rightfinger", "link7", INF, INF),
    ("leftfinger", "rightfinger", INF, INF),
];

/// The pairs a built-in Franka arm's SRDF leaves out (its links named `{prefix}_…`; the
/// hand's with `hand`), each with the closest approach the search found on its hulls.
pub(crate) fn franka_left_out(prefix: &str, fr3: bool, hand: bool) -> Vec<LeftOut> {
    let hand_part = |n: &str| n == "hand" || n.ends_with("finger");
    FRANKA_LEFT_OUT
        .iter()
        .filter(|(a, b, _, _)| hand || !(hand_part(a) || hand_part(b)))
        .map(|&(a, b, on_fr3, on_panda)| LeftOut {
            first: format!("{prefix}_{a}"),
            second: format!("{prefix}_{b}"),
            why: why_of(if fr3 { on_fr3 } else { on_panda }),
        })
        .collect()
}

const INF: f64 = f64::INFINITY;

/// What a search's closest approach says: no approach at all (infinite) for shapes that
/// ride on one frame.
fn why_of(closest: f64) -> Why {
    if closest.is_infinite() {
        Why::Fixed
    } else {
        Why::Searched(closest)
    }
}

/// The cache's format: the key it was searched for, and each pair's closest approach.
#[derive(Debug, Serialize, Deserialize)]
struct Cached {
    /// What wrote it.
    written_by: String,
    /// A hash of the search's inputs (hex).
    key: String,
    /// Each pair, its closest approach (m) and where.
    pairs: Vec<CachedPair>,
}

#[derive(Debug, Serialize, Deserialize)]
struct CachedPair {
    first: String,
    second: String,
    /// None: the shapes ride on one frame.
    closest: Option<f64>,
    witness: Vec<f64>,
}

const WRITTEN_BY: &str = "cps: the closest approach of each pair ROBOT.srdf leaves out, searched over ROBOT.urdf's joint ranges (delete to search again)";

/// The pairs `declared` by the SRDF beside `urdf` (its text `srdf`), searched over the
/// joint ranges of `chain` on `bodies` — or read from `ROBOT.pairs.json` beside the URDF
/// when it was searched for the same inputs, and written there when not (where the folder
/// cannot be written, said in `notes`). A pair on a link without shapes is kept as
/// declared.
pub(crate) fn verified(
    chain: &SerialChain,
    bodies: &[Body],
    declared: Vec<(String, String)>,
    urdf: (&Path, &str),
    srdf: &str,
    notes: &mut Vec<String>,
) -> Vec<LeftOut> {
    let has_body = |l: &str| bodies.iter().any(|b| b.link == l);
    let (searched, unplaced): (Vec<_>, Vec<_>) = declared
        .into_iter()
        .partition(|(a, b)| has_body(a) && has_body(b));
    let mut out = LeftOut::each(unplaced, Why::Declared);
    if searched.is_empty() {
        return out;
    }
    let search = NeverSearch::default();
    let key = format!("{:016x}", key(&search, urdf.1, srdf, bodies, &searched));
    let cache = urdf.0.with_extension("pairs.json");
    let approaches = match read_cache(&cache, &key, &searched) {
        Some(found) => found,
        None => {
            let found = match cps_robot::closest_approaches(chain, bodies, &searched, &search) {
                Ok(f) => f,
                Err(why) => {
                    notes.push(format!(
                        "the pairs the SRDF leaves out could not be searched ({why}): they are left out as it says"
                    ));
                    out.extend(LeftOut::each(searched, Why::Declared));
                    return out;
                }
            };
            let pairs = found
                .iter()
                .map(|f| CachedPair {
                    first: f.first.clone(),
                    second: f.second.clone(),
                    closest: f.closest.is_finite().then_some(f.closest),
                    witness: f.witness.clone(),
                })
                .collect::<Vec<_>>();
            write_cache(&cache, &key, pairs, notes);
            found.into_iter().map(|f| f.closest).collect()
        }
    };
    out.extend(
        searched
            .into_iter()
            .zip(approaches)
            .map(|((first, second), closest)| LeftOut {
                first,
                second,
                why: why_of(closest),
            }),
    );
    out
}

/// The cached closest approaches of `pairs`, when the cache at `path` was written by cps
/// for `key` and holds exactly these pairs.
fn read_cache(path: &Path, key: &str, pairs: &[(String, String)]) -> Option<Vec<f64>> {
    let text = cps_files::read::read_text(path, 1 << 20, "pairs cache").ok()?;
    let cached: Cached = serde_json::from_str(&text).ok()?;
    let same = cached.key == key
        && cached.pairs.len() == pairs.len()
        && cached
            .pairs
            .iter()
            .zip(pairs)
            .all(|(c, (a, b))| &c.first == a && &c.second == b);
    same.then(|| {
        cached
            .pairs
            .iter()
            .map(|c| c.closest.unwrap_or(f64::INFINITY))
            .collect()
    })
}

/// Writes the cache at `path` through the one writer: it replaces only a cache cps wrote
/// (a file of another kind there is left alone, said in `notes`).
fn write_cache(path: &Path, key: &str, pairs: Vec<CachedPair>, notes: &mut Vec<String>) {
    let cached = Cached {
        written_by: WRITTEN_BY.into(),
        key: key.into(),
        pairs,
    };
    let Ok(json) = serde_json::to_string_pretty(&cached) else {
        return;
    };
    let ours = |p: &Path| {
        cps_files::read::read_text(p, 1 << 20, "pairs cache")
            .ok()
            .and_then(|t| serde_json::from_str::<Cached>(&t).ok())
            .is_some_and(|c| c.written_by == WRITTEN_BY)
    };
    let output = cps_files::replace::Output::new(
        path,
        "pairs cache",
        cps_files::replace::Shape::file(ours),
        true,
    );
    let written = output
        .check()
        .and_then(|()| cps_files::replace::write_file(output, format!("{json}\n").as_bytes()));
    if let Err(e) = written {
        notes.push(format!(
            "the search of the SRDF's pairs is not kept for the next run: {e}"
        ));
    }
}

/// FNV-1a (64 bits) of everything the search depends on: its settings, the URDF and SRDF
/// texts, and every body's link, frame, placement and shape.
fn key(
    search: &NeverSearch,
    urdf: &str,
    srdf: &str,
    bodies: &[Body],
    pairs: &[(String, String)],
) -> u64 {
    let mut h = Fnv(0xcbf2_9ce4_8422_2325);
    h.bytes(b"cps-pairs-1");
    for n in [search.samples as u64, search.starts as u64, search.seed] {
        h.bytes(&n.to_le_bytes());
    }
    h.text(urdf);
    h.text(srdf);
    for (a, b) in pairs {
        h.text(a);
        h.text(b);
    }
    for body in bodies {
        h.text(&body.link);
        h.bytes(&(body.frame as u64).to_le_bytes());
        let t = body.origin.translation.vector;
        let r = body.origin.rotation.coords;
        h.numbers(t.iter().chain(r.iter()).copied());
        match &body.shape {
            Shape::Sphere { radius } => h.numbers([1.0, *radius]),
            Shape::Cuboid { half } => h.numbers([2.0, half.x, half.y, half.z]),
            Shape::Cylinder {
                radius,
                half_length,
            } => h.numbers([3.0, *radius, *half_length]),
            Shape::Capsule {
                radius,
                half_length,
            } => h.numbers([4.0, *radius, *half_length]),
            Shape::Convex(hull) => {
                h.numbers([5.0]);
                h.numbers(hull.vertices().iter().flat_map(|v| [v.x, v.y, v.z]));
            }
        }
    }
    h.0
}

struct Fnv(u64);

impl Fnv {
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 = (self.0 ^ u64::from(x)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn text(&mut self, t: &str) {
        self.bytes(&(t.len() as u64).to_le_bytes());
        self.bytes(t.as_bytes());
    }
    fn numbers(&mut self, xs: impl IntoIterator<Item = f64>) {
        for x in xs {
            self.bytes(&x.to_bits().to_le_bytes());
        }
    }
}
