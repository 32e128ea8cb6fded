//! Shared by the flagship's tuning examples: VQF's published scores on the 14 shared BROAD
//! trials (the data folder's README) and the forward-backward smoother's scores.
use rootfuse::attitude::filters::{SqrtEskf, SqrtEskfParams};
use rootfuse::attitude::smooth::forward_backward;
use rootfuse::attitude::{Dof, Recording};
use rootfuse::eval::metrics::{Alignment, evaluate};

/// VQF online RMSE (degrees): total 9D, total 6D, inclination, by trial-name prefix.
pub const VQF_ONLINE: [(&str, [f64; 3]); 14] = [
    ("02_", [1.38, 0.63, 0.429]),
    ("04_", [1.07, 3.92, 0.787]),
    ("07_", [1.75, 1.55, 1.02]),
    ("08_", [3.34, 7.92, 1.76]),
    ("10_", [1.8, 1.06, 0.299]),
    ("12_", [1.36, 1.38, 0.254]),
    ("16_", [0.742, 0.662, 0.539]),
    ("18_", [0.812, 0.84, 0.614]),
    ("24_", [1.55, 0.839, 0.607]),
    ("27_", [6.73, 1.7, 0.37]),
    ("29_", [2.38, 4.82, 1.06]),
    ("31_", [3.21, 3.05, 1.14]),
    ("33_", [3.75, 2.31, 0.599]),
    ("35_", [1.09, 3.0, 0.658]),
];

/// VQF online `[9D, 6D, inclination]` of the trial named `name`.
pub fn vqf_online(name: &str) -> Result<[f64; 3], String> {
    VQF_ONLINE
        .iter()
        .find(|(prefix, _)| name.starts_with(prefix))
        .map(|(_, v)| *v)
        .ok_or_else(|| format!("no VQF numbers for {name}"))
}

/// Offline (forward-backward smoother) RMSE: 9D total, 6D total, 9D inclination.
pub fn smoothed(p: &SqrtEskfParams, rec: &Recording) -> [f64; 3] {
    let eval = |dof: Dof, align| {
        let q = SqrtEskfParams { dof, ..p.clone() };
        let out = forward_backward(rec, || SqrtEskf::new(&q), dof.uses_magnetometer())
            .expect("sqrt-eskf has a covariance");
        evaluate(rec, &out.quat, align).map_or([f64::NAN; 2], |r| [r.total, r.inclination])
    };
    let [e9, incl] = eval(Dof::Nine, Alignment::NineD);
    let [e6, _] = eval(Dof::Six, Alignment::SixD);
    [e9, e6, incl]
}
