//! `reacher foxglove`: the view holds the log unchanged plus a Foxglove 3D scene whose
//! messages decode with the official schemas (the `foxglove` crate's types, i.e. the field
//! names `entities`, `spheres`, `cylinders`, `pose`, `position`, …), and whose geometry agrees
//! with the log (balls at the logged layout, a lit touch zone exactly when a label says the
//! fingertip touches that ball, the event letter "c" on the cancel step).

use foxglove::schemas::{FrameTransforms, SceneUpdate};
use foxglove::Decode;
use smirl::env::reacher::ReacherConfig;
use smirl::log::demo::{log_scripted_demos, DemoSpec};
use smirl::log::schema::StepMsg;
use smirl::log::{read_log, LogOptions};
use smirl::pipeline::foxglove_scene::{export_scene, FRAME_WORLD, TOPIC_SCENE, TOPIC_TF};

#[allow(unused_imports)]
use shipped_layout::{layout, obs_dim, shipped_config};
mod shipped_layout;

#[test]
fn the_scene_decodes_with_the_official_schemas_and_matches_the_log() {
    let dir = tempfile::tempdir().unwrap();
    let log_path = dir.path().join("if.mcap");
    log_scripted_demos(
        &log_path,
        &DemoSpec {
            task: "if".into(),
            sequence: "br".into(),
            episodes: 3,
            seed: 11,
            stop_when_done: true,
            // The task's event schedule, with the event in every episode.
            env: ReacherConfig::default(),
            event_probability: Some(1.0),
            reward_machine: Some(smirl::rm::perfect::load("reacher_if").unwrap()),
        },
        LogOptions::default(),
    )
    .unwrap();
    let original = std::fs::read(&log_path).unwrap();
    let view = dir.path().join("view.mcap");
    let summary = export_scene(&log_path, &view, false).unwrap();
    assert_eq!(
        std::fs::read(&log_path).unwrap(),
        original,
        "the log is not touched"
    );

    // The log's own content is all there: it reads back to the same episodes.
    let log = read_log(&log_path).unwrap();
    assert_eq!(read_log(&view).unwrap().episodes, log.episodes);
    let states: usize = log.episodes.iter().map(|e| e.steps.len() + 1).sum();
    assert_eq!(summary.scenes as usize, states);

    let bytes = std::fs::read(&view).unwrap();
    let (mut scenes, mut transforms, mut touches, mut cancels) = (0, 0, 0, 0);
    let mut balls: Vec<[f64; 2]> = Vec::new();
    let mut last_step: Option<StepMsg> = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        match m.channel.topic.as_str() {
            "/step" => last_step = Some(StepMsg::decode(&m.data).unwrap()),
            "/episode/start" => last_step = None,
            TOPIC_TF => {
                let schema = m.channel.schema.as_ref().unwrap();
                assert_eq!(
                    (schema.name.as_str(), schema.encoding.as_str()),
                    ("foxglove.FrameTransforms", "protobuf")
                );
                let tf = FrameTransforms::decode(&m.data[..]).unwrap();
                let children: Vec<_> = tf
                    .transforms
                    .iter()
                    .map(|t| t.child_frame_id.as_str())
                    .collect();
                assert_eq!(children, ["link0", "link1", "fingertip"]);
                transforms += 1;
            }
            TOPIC_SCENE => {
                let schema = m.channel.schema.as_ref().unwrap();
                assert_eq!(
                    (schema.name.as_str(), schema.encoding.as_str()),
                    ("foxglove.SceneUpdate", "protobuf")
                );
                assert_eq!(m.channel.message_encoding, "protobuf");
                let scene = SceneUpdate::decode(&m.data[..]).unwrap();
                scenes += 1;
                let entity = |id: &str| scene.entities.iter().find(|e| e.id == id);
                for e in &scene.entities {
                    assert_eq!(e.frame_id, FRAME_WORLD);
                }
                if let Some(b) = entity("balls") {
                    assert!(last_step.is_none(), "balls are sent at episode starts");
                    assert_eq!(b.spheres.len(), 4);
                    balls = b
                        .spheres
                        .iter()
                        .map(|s| {
                            let p = s.pose.unwrap().position.unwrap();
                            [p.x, p.y]
                        })
                        .collect();
                    assert_eq!(entity("arena").unwrap().cylinders.len(), 4);
                }
                let arm = entity("arm").unwrap();
                assert_eq!((arm.cylinders.len(), arm.spheres.len()), (2, 1));
                let tip = arm.spheres[0].pose.unwrap().position.unwrap();
                let events = entity("events").unwrap();
                let Some(step) = &last_step else { continue };
                // A lit zone for exactly the touched balls, and the fingertip really there.
                let touched: Vec<usize> = (0..4).filter(|k| step.labels >> k & 1 == 1).collect();
                assert_eq!(events.spheres.len(), touched.len());
                for &k in &touched {
                    let d = ((tip.x - balls[k][0]).powi(2) + (tip.y - balls[k][1]).powi(2)).sqrt();
                    assert!(
                        d < layout().regions[0].radius + 1e-9,
                        "ball {k}: fingertip {d} m away"
                    );
                    touches += 1;
                }
                let cancel = step.labels >> layout().event_bit(0) & 1 == 1;
                assert_eq!(events.texts.iter().any(|t| t.text == "c"), cancel);
                cancels += usize::from(cancel);
            }
            _ => {}
        }
    }
    assert_eq!((scenes, transforms), (states, states));
    assert!(touches > 0, "the scripted demos touch balls");
    assert_eq!(cancels, 3, "one cancel per episode (probability 1)");
}
