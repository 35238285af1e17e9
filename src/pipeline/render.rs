//! A top-down picture of one logged ReacherDelivery episode, as PNG: the arena, the task's
//! regions in their scene colours (at the episode's logged layout), the fingertip's path, the
//! arm at a few time points (lighter = earlier), every touch (a ring in the region's colour
//! where the fingertip first touched it) and the first event's step (a black cross at the
//! fingertip), plus a timeline strip under the arena with the same events.
//!
//! Positions come from MuJoCo's forward kinematics on the model XML stored in the log and the
//! logged `qpos` of every step, so the picture shows the episode as it was simulated.

use crate::atomic_file::write_atomic;
use crate::env::layout::TaskLayout;
use crate::env::reacher_task::{Branch, EventBranch};
use crate::log::{LoggedEpisode, RolloutLog};
use crate::mujoco::{Data, Model, ObjectKind};
use crate::report::raster::{Canvas, Rgb};
use crate::rm::LabelSet;
use std::path::Path;
use std::sync::Arc;

/// What to draw and how large.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Side of the square arena picture in pixels (the timeline strip adds below it).
    pub size: u32,
    /// Arm poses drawn, evenly spaced from the first to the last state (at least 1).
    pub poses: usize,
}

impl RenderOptions {
    /// Smallest and largest picture side accepted, in pixels.
    pub const SIZES: std::ops::RangeInclusive<u32> = 64..=8192;

    /// Checks the options on their own (before any log is read).
    pub fn validate(&self) -> Result<(), RenderError> {
        if !Self::SIZES.contains(&self.size) {
            return Err(RenderError::Options {
                problem: format!(
                    "picture size {} must be between {} and {} pixels",
                    self.size,
                    Self::SIZES.start(),
                    Self::SIZES.end()
                ),
            });
        }
        Ok(())
    }
}

impl Default for RenderOptions {
    fn default() -> RenderOptions {
        RenderOptions {
            size: 480,
            poses: 5,
        }
    }
}

/// A picture that cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("{problem}")]
    Options { problem: String },
    #[error("{path}: {problem}")]
    Input { path: String, problem: String },
    #[error("{path}: cannot write: {source}")]
    Write {
        path: String,
        #[source]
        source: std::io::Error,
    },
}

/// A rendered episode and what it shows.
#[derive(Clone, Debug)]
pub struct EpisodePicture {
    pub canvas: Canvas,
    pub episode: u64,
    pub phase: String,
    pub steps: usize,
    /// Touches as (1-based step, region letter), first contact of each touch.
    pub touches: Vec<(usize, char)>,
    /// 1-based step of the first event, when an event fired within the logged steps.
    pub event_step: Option<usize>,
    /// For a conditional task (IF, Composite): the branch the episode took, by the run's
    /// reward machine along the logged labels.
    pub branch: Option<Branch>,
    /// Region centres in pixels, in label-bit order.
    pub ball_pixels: Vec<(f64, f64)>,
    /// Fingertip at the first and last state, in pixels.
    pub tip_pixels: ((f64, f64), (f64, f64)),
}

/// Half-width of the pictured square in metres: fits the shipped arena (walls at ±0.3 plus
/// their 0.02 radius); a model with a larger arena is drawn clipped.
const VIEW_HALF: f64 = 0.33;
/// The arena wall geoms of `assets/reacher_delivery.xml`.
const WALLS: [&str; 4] = ["sideS", "sideE", "sideN", "sideW"];
/// Height of the timeline strip in pixels.
const STRIP: u32 = 28;

/// The arena's square of `size` pixels: world metres to pixels.
#[derive(Clone, Copy)]
struct Pixels {
    /// Pixels per metre.
    scale: f64,
}

impl Pixels {
    fn of(size: u32) -> Pixels {
        Pixels {
            scale: f64::from(size) / (2.0 * VIEW_HALF),
        }
    }

    /// World (x, y) in metres to pixel (x, y), y up in the world, down in the image.
    fn at(self, [x, y]: [f64; 2]) -> (f64, f64) {
        ((x + VIEW_HALF) * self.scale, (VIEW_HALF - y) * self.scale)
    }
}

fn colour(rgba: [f32; 4]) -> Rgb {
    Rgb(rgba[0], rgba[1], rgba[2])
}

/// Colours of regions whose anchor names no geom, in label-bit order (cycled).
const REGION_PALETTE: [Rgb; 4] = [
    Rgb(0.55, 0.35, 0.75),
    Rgb(0.95, 0.55, 0.1),
    Rgb(0.2, 0.65, 0.65),
    Rgb(0.6, 0.6, 0.2),
];

/// How each region of `layout` is drawn, in label-bit order: the colour and radius of the geom
/// named as its anchor (the built-in scene's balls), or a colour of the palette and radius 0
/// (no solid centre) when no geom has that name.
pub fn region_looks(model: &Model, layout: &TaskLayout) -> Vec<(Rgb, f64)> {
    (layout.regions.iter().enumerate())
        .map(
            |(k, region)| match model.id(ObjectKind::Geom, region.anchor.name()) {
                Ok(g) => (colour(model.geom_rgba(g)), model.geom_radius(g)),
                Err(_) => (REGION_PALETTE[k % REGION_PALETTE.len()], 0.0),
            },
        )
        .collect()
}

/// Renders episode `episode` (its id in the log, as `reacher replay` prints it; `None` = the
/// first logged episode).
pub fn render_episode(
    log: &RolloutLog,
    episode: Option<u64>,
    options: &RenderOptions,
) -> Result<EpisodePicture, RenderError> {
    let path = log.path.display().to_string();
    let bad = |problem: String| RenderError::Input {
        path: path.clone(),
        problem,
    };
    options.validate()?;
    // A log without a scene is refused before its episodes are looked at.
    log.reacher_model_xml().map_err(&bad)?;
    let ep = pick_episode(log, episode, &path)?;
    let model = Arc::new(log.reacher_model().map_err(|e| bad(e.to_string()))?);
    let bodies = arm_bodies(&model).map_err(&bad)?;
    let mut looks = SceneLooks::of(&model).map_err(&bad)?;
    let layout = log.run.task_layout().map_err(|e| bad(e.to_string()))?;
    (looks.ball_colours, looks.ball_radii) = region_looks(&model, &layout).into_iter().unzip();
    if ep.start.balls.len() != 2 * layout.n_regions() {
        return Err(bad(format!(
            "episode {}: {} region coordinates, expected {}",
            ep.start.episode,
            ep.start.balls.len(),
            2 * layout.n_regions()
        )));
    }
    let arm = arm_positions(&model, bodies, ep).map_err(&bad)?;

    let size = options.size;
    let pixels = Pixels::of(size);
    let mut canvas = Canvas::new(size, size + STRIP, Rgb::WHITE);
    draw_arena(&mut canvas, &looks, pixels);
    let ball_pixels = draw_regions(&mut canvas, &looks, &layout, ep, pixels);
    draw_poses(&mut canvas, &looks, &arm, options.poses, pixels);
    let letters: Vec<char> = log.run.vocabulary.chars().collect();
    let (touches, event_step) =
        draw_touches(&mut canvas, &looks, &layout, ep, &arm, &letters, pixels);
    draw_timeline(
        &mut canvas,
        &looks,
        ep,
        &touches,
        event_step,
        &letters,
        size,
    );
    let branch = super::replay::run_reward_machine(log, &mut Vec::new())
        .ok()
        .flatten()
        .and_then(|(rm, _)| {
            let branches = EventBranch::of(&rm, layout.events())?;
            Some(branches.of_labels(&rm, ep.steps.iter().map(|s| LabelSet(s.labels))))
        });
    Ok(EpisodePicture {
        canvas,
        branch,
        episode: ep.start.episode,
        phase: ep.start.phase.clone(),
        steps: ep.steps.len(),
        touches,
        event_step,
        ball_pixels,
        tip_pixels: (pixels.at(arm[0][2]), pixels.at(arm[arm.len() - 1][2])),
    })
}

/// The colours and sizes the picture takes from the logged model: the arm's links and
/// fingertip, the arena walls (capsules of the world body, drawn in the first wall's colour)
/// and each region's ball ([`region_looks`]).
struct SceneLooks {
    link: Rgb,
    tip: Rgb,
    wall: Rgb,
    /// Each wall's end points and radius.
    walls: Vec<([f64; 2], [f64; 2], f64)>,
    ball_colours: Vec<Rgb>,
    ball_radii: Vec<f64>,
}

impl SceneLooks {
    /// The arm's and the walls' looks; the balls' are the task layout's, set after.
    fn of(model: &Model) -> Result<SceneLooks, String> {
        let id = |kind, name: &str| model.id(kind, name).map_err(|e| e.to_string());
        let link = colour(model.geom_rgba(id(ObjectKind::Geom, "link0")?));
        let tip = colour(model.geom_rgba(id(ObjectKind::Geom, "fingertip")?));
        let wall = colour(model.geom_rgba(id(ObjectKind::Geom, WALLS[0])?));
        let mut walls = Vec::with_capacity(WALLS.len());
        for name in WALLS {
            let g = id(ObjectKind::Geom, name)?;
            let (a, b) = model.world_capsule_segment(g).ok_or_else(|| {
                format!("model.xml: wall {name} is not a capsule of the world body")
            })?;
            walls.push(([a[0], a[1]], [b[0], b[1]], model.geom_radius(g)));
        }
        Ok(SceneLooks {
            link,
            tip,
            wall,
            walls,
            ball_colours: Vec::new(),
            ball_radii: Vec::new(),
        })
    }
}

/// The arm's bodies: shoulder, elbow, fingertip.
fn arm_bodies(model: &Model) -> Result<[usize; 3], String> {
    let id = |name: &str| model.id(ObjectKind::Body, name).map_err(|e| e.to_string());
    let elbow = id("body1")?;
    let tip = id("fingertip")?;
    let shoulder = id("body0")?;
    Ok([shoulder, elbow, tip])
}

/// The arm's positions (shoulder, elbow, fingertip) at the start and after every step, by
/// forward kinematics of the logged joint angles.
fn arm_positions(
    model: &Arc<Model>,
    [shoulder, elbow, tip]: [usize; 3],
    ep: &LoggedEpisode,
) -> Result<Vec<[[f64; 2]; 3]>, String> {
    let mut data = Data::new(model.clone()).map_err(|e| e.to_string())?;
    let states = std::iter::once(&ep.start.qpos).chain(ep.steps.iter().map(|s| &s.qpos));
    let mut arm = Vec::with_capacity(ep.steps.len() + 1);
    for (k, qpos) in states.enumerate() {
        data.set_qpos(qpos)
            .and_then(|()| data.forward())
            .map_err(|e| format!("episode {} state {k}: {e}", ep.start.episode))?;
        let xy = |b: usize| {
            let p = data.body_xpos(b);
            [p[0], p[1]]
        };
        arm.push([xy(shoulder), xy(elbow), xy(tip)]);
    }
    Ok(arm)
}

/// The arena's floor (the walls' bounding box) and its walls.
fn draw_arena(canvas: &mut Canvas, looks: &SceneLooks, pixels: Pixels) {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in looks.walls.iter().flat_map(|(a, b, _)| [a, b]) {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let (a0, a1) = (pixels.at([lo[0], hi[1]]), pixels.at([hi[0], lo[1]]));
    canvas.rect(
        a0.0 as i64,
        a0.1 as i64,
        a1.0 as i64,
        a1.1 as i64,
        Rgb(0.93, 0.93, 0.93),
        1.0,
    );
    for &(a, b, radius) in &looks.walls {
        canvas.line(
            pixels.at(a),
            pixels.at(b),
            2.0 * radius * pixels.scale,
            looks.wall,
            1.0,
        );
    }
}

/// The regions at the episode's start: the touch zone lightly, the ball itself solid. Returns
/// each region's centre in pixels.
fn draw_regions(
    canvas: &mut Canvas,
    looks: &SceneLooks,
    layout: &TaskLayout,
    ep: &LoggedEpisode,
    pixels: Pixels,
) -> Vec<(f64, f64)> {
    let mut ball_pixels = Vec::with_capacity(layout.n_regions());
    for (i, c) in looks.ball_colours.iter().enumerate() {
        let centre = pixels.at([ep.start.balls[2 * i], ep.start.balls[2 * i + 1]]);
        ball_pixels.push(centre);
        let (ball_radius, touch_radius) = (looks.ball_radii[i], layout.regions[i].radius);
        canvas.disc(
            centre.0,
            centre.1,
            (ball_radius + touch_radius) * pixels.scale,
            c.lighten(0.75),
            1.0,
        );
        if ball_radius > 0.0 {
            canvas.disc(centre.0, centre.1, ball_radius * pixels.scale, *c, 1.0);
        }
    }
    ball_pixels
}

/// `poses` arm poses spread over the episode, earliest lightest, and the fingertip's path.
fn draw_poses(
    canvas: &mut Canvas,
    looks: &SceneLooks,
    arm: &[[[f64; 2]; 3]],
    poses: usize,
    pixels: Pixels,
) {
    let n = arm.len();
    let poses = poses.max(1).min(n);
    for k in 0..poses {
        let idx = if poses == 1 {
            n - 1
        } else {
            k * (n - 1) / (poses - 1)
        };
        let fade = 0.8 * (1.0 - (k + 1) as f32 / poses as f32);
        let [s, e, t] = arm[idx];
        let w = 0.02 * pixels.scale;
        canvas.line(pixels.at(s), pixels.at(e), w, looks.link.lighten(fade), 1.0);
        canvas.line(pixels.at(e), pixels.at(t), w, looks.link.lighten(fade), 1.0);
        canvas.disc(
            pixels.at(t).0,
            pixels.at(t).1,
            0.01 * pixels.scale,
            looks.tip.lighten(fade),
            1.0,
        );
    }
    let path_colour = looks.tip.darken(0.55);
    for w in arm.windows(2) {
        canvas.line(
            pixels.at(w[0][2]),
            pixels.at(w[1][2]),
            2.0,
            path_colour,
            1.0,
        );
    }
}

/// Each touch (a rising edge of a region's label) as a ring at the fingertip, and the first
/// event's step as a cross. Returns the touches (step, region letter) and that step.
fn draw_touches(
    canvas: &mut Canvas,
    looks: &SceneLooks,
    layout: &TaskLayout,
    ep: &LoggedEpisode,
    arm: &[[[f64; 2]; 3]],
    letters: &[char],
    pixels: Pixels,
) -> (Vec<(usize, char)>, Option<usize>) {
    let mut touches = Vec::new();
    let mut event_step = None;
    let events = layout.events().0;
    let mut prev = ep.start.labels;
    for (k, s) in ep.steps.iter().enumerate() {
        let step = k + 1;
        let tip_px = pixels.at(arm[step][2]);
        for (b, c) in looks.ball_colours.iter().enumerate() {
            let bit = 1 << b;
            if s.labels & bit != 0 && prev & bit == 0 {
                touches.push((step, letters.get(b).copied().unwrap_or('?')));
                canvas.ring(
                    tip_px.0,
                    tip_px.1,
                    0.018 * pixels.scale,
                    3.0,
                    Rgb::BLACK,
                    1.0,
                );
                canvas.ring(tip_px.0, tip_px.1, 0.018 * pixels.scale, 1.5, *c, 1.0);
            }
        }
        if s.labels & events != 0 && event_step.is_none() {
            event_step = Some(step);
            let d = 0.015 * pixels.scale;
            for (dx, dy) in [(d, d), (d, -d)] {
                canvas.line(
                    (tip_px.0 - dx, tip_px.1 - dy),
                    (tip_px.0 + dx, tip_px.1 + dy),
                    3.0,
                    Rgb::BLACK,
                    1.0,
                );
            }
        }
        prev = s.labels;
    }
    (touches, event_step)
}

/// The timeline under the arena: a grey bar over the episode's steps, a tick in the region's
/// colour at each touch and a black one at the event's step.
fn draw_timeline(
    canvas: &mut Canvas,
    looks: &SceneLooks,
    ep: &LoggedEpisode,
    touches: &[(usize, char)],
    event_step: Option<usize>,
    letters: &[char],
    size: u32,
) {
    let (left, right) = (8.0, f64::from(size) - 8.0);
    let top = f64::from(size) + 6.0;
    let bottom = f64::from(size + STRIP) - 6.0;
    let mid = (top + bottom) / 2.0;
    canvas.line((left, mid), (right, mid), 4.0, Rgb(0.75, 0.75, 0.75), 1.0);
    let at = |step: usize| left + (right - left) * step as f64 / ep.steps.len().max(1) as f64;
    for &(step, letter) in touches {
        let b = letters.iter().position(|&c| c == letter).unwrap_or(0);
        let x = at(step);
        let c = looks.ball_colours.get(b).copied().unwrap_or(Rgb::BLACK);
        canvas.line((x, top), (x, bottom), 3.0, c, 1.0);
    }
    if let Some(step) = event_step {
        let x = at(step);
        canvas.line((x, top), (x, bottom), 2.0, Rgb::BLACK, 1.0);
    }
}

/// The episode with id `episode` (the first one for `None`).
fn pick_episode<'a>(
    log: &'a RolloutLog,
    episode: Option<u64>,
    path: &str,
) -> Result<&'a LoggedEpisode, RenderError> {
    let ids = || {
        let ids: Vec<String> = log
            .episodes
            .iter()
            .take(12)
            .map(|e| e.start.episode.to_string())
            .collect();
        let more = if log.episodes.len() > 12 { ", …" } else { "" };
        format!(
            "{} logged episode(s): {}{more}",
            log.episodes.len(),
            ids.join(", ")
        )
    };
    match episode {
        None => log
            .episodes
            .first()
            .ok_or_else(|| "the log has no episodes".to_string()),
        Some(id) => log
            .episodes
            .iter()
            .find(|e| e.start.episode == id)
            .ok_or_else(|| format!("episode {id} is not in the log ({})", ids())),
    }
    .map_err(|problem| RenderError::Input {
        path: path.into(),
        problem,
    })
}

/// Writes the picture as PNG at `path`, atomically (a failed write leaves no file that looks
/// complete).
pub fn write_png(path: &Path, picture: &EpisodePicture) -> Result<(), RenderError> {
    let io = |source| RenderError::Write {
        path: path.display().to_string(),
        source,
    };
    let bytes = picture
        .canvas
        .to_png()
        .map_err(|e| io(std::io::Error::other(e.to_string())))?;
    write_atomic(path, &bytes).map_err(io)
}
