//! A learned movement as `visualization_msgs/MarkerArray`: the path as a line strip, the
//! via points as spheres, the start and goal as larger spheres with their names, all in
//! one frame, for RViz or Foxglove; and shapes (a robot's links, a scene's obstacles) as
//! triangle lists, which both viewers draw without a mesh file.

use cps_ros2_msg::msg::{Header, Marker, MarkerArray};

/// Marker types used here.
const SPHERE: i32 = 2;
const LINE_STRIP: i32 = 4;
const SPHERE_LIST: i32 = 7;
const TEXT: i32 = 9;
const TRIANGLE_LIST: i32 = 11;

/// A shape as a triangle-list marker: `triangles`' corners (in the shape's own frame) at
/// `pose` (position, quaternion `[x, y, z, w]`) in `frame`, one colour.
pub fn mesh_marker(
    frame: &str,
    ns: &str,
    id: i32,
    pose: ([f64; 3], [f64; 4]),
    triangles: Vec<[f64; 3]>,
    color: [f32; 4],
) -> Marker {
    Marker {
        header: Header {
            frame_id: frame.to_string(),
            ..Header::default()
        },
        ns: ns.into(),
        id,
        kind: TRIANGLE_LIST,
        position: pose.0,
        orientation: pose.1,
        scale: [1.0; 3],
        color,
        points: triangles,
        ..Marker::default()
    }
}

/// The markers of a path (m, in `frame`), its via points and its goal; namespace `cps`.
pub fn path_markers(frame: &str, path: &[[f64; 3]], via: &[[f64; 3]]) -> MarkerArray {
    let header = Header {
        frame_id: frame.to_string(),
        ..Header::default()
    };
    let mut markers = vec![Marker {
        header: header.clone(),
        ns: "cps".into(),
        id: 0,
        kind: LINE_STRIP,
        scale: [0.005, 0.0, 0.0],
        color: [0.12, 0.47, 0.71, 1.0],
        points: path.to_vec(),
        ..Marker::default()
    }];
    if !via.is_empty() {
        markers.push(Marker {
            header: header.clone(),
            ns: "cps".into(),
            id: 1,
            kind: SPHERE_LIST,
            scale: [0.02; 3],
            color: [1.0, 0.5, 0.05, 1.0],
            points: via.to_vec(),
            ..Marker::default()
        });
    }
    let ends = [
        (path.first(), "start", [0.17, 0.63, 0.17, 1.0]),
        (path.last(), "goal", [0.84, 0.15, 0.16, 1.0]),
    ];
    for (k, (at, word, color)) in ends.into_iter().enumerate() {
        let Some(&p) = at else { continue };
        let id = 2 + 2 * k as i32;
        markers.push(Marker {
            header: header.clone(),
            ns: "cps".into(),
            id,
            kind: SPHERE,
            position: p,
            scale: [0.03; 3],
            color,
            ..Marker::default()
        });
        markers.push(Marker {
            header: header.clone(),
            ns: "cps".into(),
            id: id + 1,
            kind: TEXT,
            position: [p[0], p[1], p[2] + 0.04],
            scale: [0.0, 0.0, 0.03],
            color,
            text: word.into(),
            ..Marker::default()
        });
    }
    MarkerArray { markers }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_gives_a_line_the_via_points_and_both_ends() {
        let path = [[0.0, 0.0, 0.5], [0.1, 0.0, 0.5], [0.2, 0.1, 0.4]];
        let m = path_markers("panda_link0", &path, &[[0.1, 0.0, 0.5]]);
        assert_eq!(m.markers.len(), 6);
        assert_eq!(m.markers[0].points, path);
        assert_eq!(m.markers[1].points, [[0.1, 0.0, 0.5]]);
        assert_eq!(m.markers[4].position, [0.2, 0.1, 0.4]);
        assert_eq!(m.markers[5].text, "goal");
        let ids: std::collections::HashSet<i32> = m.markers.iter().map(|k| k.id).collect();
        assert_eq!(ids.len(), 6, "ids are unique within the namespace");
        assert!(m.markers.iter().all(|k| k.header.frame_id == "panda_link0"));
        assert_eq!(path_markers("w", &[], &[]).markers.len(), 1);
    }
}
