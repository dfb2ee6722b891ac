//! What can go wrong with shapes and meshes, in sentences that name the place.

/// A shape or mesh cps cannot use.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    /// The points span no volume.
    #[error("{what} is flat: {why}")]
    Flat {
        /// The shape's or file's name.
        what: String,
        /// Why (one line, all in one plane, too few points).
        why: String,
    },
    /// A point with a coordinate that is not a number.
    #[error("{what}: point {} is not a number", index + 1)]
    NotFinite {
        /// The shape's or file's name.
        what: String,
        /// 0-based index of the point.
        index: usize,
    },
    /// A size that is not a positive number.
    #[error("{what}: the {quantity} {value} is not a positive number of metres")]
    Size {
        /// The shape's name.
        what: String,
        /// `radius`, `size`, `length`.
        quantity: &'static str,
        /// The value given.
        value: f64,
    },
    /// A mesh file that cannot be read.
    #[error("{file}: {why}")]
    Mesh {
        /// The file, with the line (and column) where it applies.
        file: String,
        /// What is wrong.
        why: String,
    },
}
