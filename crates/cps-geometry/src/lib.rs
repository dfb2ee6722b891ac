//! Shapes and exact signed distances for collision checking: spheres, boxes, cylinders,
//! capsules, and meshes read from STL and OBJ files as their convex hulls; the distance
//! between two of them at their poses by GJK, and their depth of overlap by EPA.
//!
//! This is the geometry cps checks robots against (their own links and their scene): it
//! knows shapes and poses, nothing of robots, and reads no file but meshes.
//!
//! ```
//! use cps_geometry::{Shape, distance};
//! use nalgebra::{Isometry3, Vector3};
//!
//! let ball = Shape::sphere(0.1, "ball")?;
//! let table = Shape::cuboid([1.0, 1.0, 0.05], "table")?;
//! // The ball's centre 0.2 m above the table's centre: 0.2 − 0.025 − 0.1 = 0.075 m apart.
//! let up = Isometry3::translation(0.0, 0.0, 0.2);
//! let s = distance(&ball, &up, &table, &Isometry3::identity());
//! assert!((s.distance - 0.075).abs() < 1e-9);
//! assert!((s.normal - -Vector3::z()).norm() < 1e-9); // from the ball towards the table
//! # Ok::<(), cps_geometry::GeometryError>(())
//! ```

mod error;
mod gjk;
mod hull;
mod mesh;
mod model;
mod shape;
mod surface;

pub use error::GeometryError;

/// The largest size and distance from the origin a shape may have (m): a robot's cell,
/// its floor included, is well inside; sizes of 1e15 m made GJK's sums lose the arm.
pub const MAX_EXTENT: f64 = 100.0;
pub use hull::Hull;
pub use mesh::{MAX_MESH_BYTES, Mesh};
pub use model::{Body, CollisionModel, Contact, Obstacle, Other, PathCheck};
pub use shape::{DISTANCE_TOLERANCE, Separation, Shape, distance, distance_bound, distance_hinted};
pub use surface::{ROUND_SEGMENTS, Surface};
