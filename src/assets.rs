//! The files the programs need at run time, built into the binaries so that an installed or
//! copied binary runs without the source tree: the ReacherDelivery model, the shipped task
//! files, the perfect reward machines and the committed expert policies. Each is the file of the same name in the
//! source tree at build time (`include_str!`/`include_bytes!`, rebuilt when it changes).

/// File name of the ReacherDelivery model (as logs record it).
pub const REACHER_XML_NAME: &str = "reacher_delivery.xml";

/// `assets/reacher_delivery.xml`: the balls are mocap bodies, the arm's joints the whole state.
pub const REACHER_XML: &str = include_str!("../assets/reacher_delivery.xml");

/// File name of the first ReacherDelivery model.
pub const REACHER_V1_XML_NAME: &str = "reacher_delivery_v1.xml";

/// `assets/reacher_delivery_v1.xml`: the same arm, each ball on two slide joints (qpos holds
/// the arm's two joints, then x and y of each ball). Logs that record it replay with it.
pub const REACHER_V1_XML: &str = include_str!("../assets/reacher_delivery_v1.xml");

/// Every ReacherDelivery model the programs ship, newest first: (file name, XML text).
pub const REACHER_MODELS: [(&str, &str); 2] = [
    (REACHER_XML_NAME, REACHER_XML),
    (REACHER_V1_XML_NAME, REACHER_V1_XML),
];

/// `assets/rm/<name>.txt`, for the names of [`crate::rm::perfect::NAMES`].
pub fn reward_machine(name: &str) -> Option<&'static str> {
    Some(match name {
        "office_t0" => include_str!("../assets/rm/office_t0.txt"),
        "office_t1" => include_str!("../assets/rm/office_t1.txt"),
        "office_t2" => include_str!("../assets/rm/office_t2.txt"),
        "office_t3" => include_str!("../assets/rm/office_t3.txt"),
        "office_t4" => include_str!("../assets/rm/office_t4.txt"),
        "reacher_or" => include_str!("../assets/rm/reacher_or.txt"),
        "reacher_sequential" => include_str!("../assets/rm/reacher_sequential.txt"),
        "reacher_if" => include_str!("../assets/rm/reacher_if.txt"),
        "reacher_composite" => include_str!("../assets/rm/reacher_composite.txt"),
        "reacher_blue" => include_str!("../assets/rm/reacher_blue.txt"),
        _ => return None,
    })
}

/// `assets/tasks/<name>.toml`, for the names of [`crate::env::task_file::SHIPPED`].
pub fn task_file(name: &str) -> Option<&'static str> {
    Some(match name {
        "or" => include_str!("../assets/tasks/or.toml"),
        "sequential" => include_str!("../assets/tasks/sequential.toml"),
        "if" => include_str!("../assets/tasks/if.toml"),
        "composite" => include_str!("../assets/tasks/composite.toml"),
        "blue" => include_str!("../assets/tasks/blue.toml"),
        _ => return None,
    })
}

/// `experiments/experts/cache/expert_<task>.policy`, the committed SAC expert of a
/// ReacherDelivery task (`or`, `sequential`, `if`, `composite`, `blue`).
pub fn expert_policy(task: &str) -> Option<&'static [u8]> {
    Some(match task {
        "or" => include_bytes!("../experiments/experts/cache/expert_or.policy"),
        "sequential" => include_bytes!("../experiments/experts/cache/expert_sequential.policy"),
        "if" => include_bytes!("../experiments/experts/cache/expert_if.policy"),
        "composite" => include_bytes!("../experiments/experts/cache/expert_composite.policy"),
        "blue" => include_bytes!("../experiments/experts/cache/expert_blue.policy"),
        _ => return None,
    })
}
