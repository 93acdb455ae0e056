//! The master's pacing (paper §4.3: the wait heuristic or a fixed frame rate) from the
//! scene file's `[render.display]` and the command line, field by field.

use gridlight_actors::pacing::{Heuristic, Pacing};

use super::DisplayDesc;

/// Pacing overrides, field by field: command line first, then the scene file.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PacingOverrides {
    pub fps: Option<f32>,
    pub q_min: Option<f64>,
    pub q_max: Option<f64>,
    pub i_min: Option<f64>,
    pub i_max: Option<f64>,
}

/// The master's pacing from the scene's `[render.display]` and the command line's
/// `cli`: a fixed rate when either asks for one (the command line's heuristic bounds
/// win over the scene's rate), else the wait heuristic with the paper's values for
/// what neither gives.
pub fn display_pacing(scene: &DisplayDesc, cli: &PacingOverrides) -> Pacing {
    let cli_bounds = [cli.q_min, cli.q_max, cli.i_min, cli.i_max].iter().any(Option::is_some);
    if let Some(fps) = cli.fps.or(if cli_bounds { None } else { scene.fps }) {
        return Pacing::FixedFps(fps);
    }
    let d = Heuristic::default();
    Pacing::Heuristic(Heuristic {
        q_min: cli.q_min.or(scene.q_min).unwrap_or(d.q_min),
        q_max: cli.q_max.or(scene.q_max).unwrap_or(d.q_max),
        i_min: cli.i_min.or(scene.i_min).unwrap_or(d.i_min),
        i_max: cli.i_max.or(scene.i_max).unwrap_or(d.i_max),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_line_wins_field_by_field_over_the_scene() {
        let scene = DisplayDesc { q_min: Some(0.3), q_max: Some(0.8), ..DisplayDesc::default() };
        let cli = PacingOverrides { q_max: Some(0.9), ..PacingOverrides::default() };
        let Pacing::Heuristic(h) = display_pacing(&scene, &cli) else { panic!("heuristic") };
        assert_eq!((h.q_min, h.q_max), (0.3, 0.9));
        assert_eq!(h.i_min, Heuristic::default().i_min, "paper value where neither says");
    }

    #[test]
    fn a_rate_in_the_scene_yields_to_heuristic_flags_and_to_a_rate_flag() {
        let scene = DisplayDesc { fps: Some(12.0), ..DisplayDesc::default() };
        assert_eq!(display_pacing(&scene, &PacingOverrides::default()), Pacing::FixedFps(12.0));
        let fps = PacingOverrides { fps: Some(30.0), ..PacingOverrides::default() };
        assert_eq!(display_pacing(&scene, &fps), Pacing::FixedFps(30.0));
        let bounds = PacingOverrides { q_min: Some(0.5), ..PacingOverrides::default() };
        assert!(matches!(display_pacing(&scene, &bounds), Pacing::Heuristic(_)));
    }
}
