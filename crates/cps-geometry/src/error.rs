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
    /// A point with a coordinate that is not a number, or farther than
    /// [`crate::MAX_EXTENT`] from its frame's origin.
    #[error("{what}: point {} is not a number of metres within {} of the origin", index + 1, crate::MAX_EXTENT)]
    NotFinite {
        /// The shape's or file's name.
        what: String,
        /// 0-based index of the point.
        index: usize,
    },
    /// A size that is not a positive number of metres.
    #[error("{what}: the {quantity} {} is not a positive number of metres", cps_files::number(*value, 6))]
    Size {
        /// The shape's name.
        what: String,
        /// `radius`, `size`, `length`.
        quantity: &'static str,
        /// The value given.
        value: f64,
    },
    /// A size larger than [`crate::MAX_EXTENT`].
    #[error("{what}: the {quantity} {} m is larger than the {} m of a robot's cell (metres, not millimetres?)", cps_files::number(*value, 6), crate::MAX_EXTENT)]
    Extent {
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
