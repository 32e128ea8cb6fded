//! One parameter set of the flagship `sqrt-eskf` on the shared BROAD trials: runs the filter
//! once per trial in 9D (its 6D estimate is the same state without the magnetic heading
//! offset, see `SqrtEskf::quat6`) and prints total RMSE 9D and 6D and the inclination RMSE per
//! trial (`!` where not below VQF online), the means, and the objective of
//! `examples/flagship_cv.rs` (mean ratio to VQF online). The cross-validated tuning itself is
//! `examples/flagship_cv.rs`.
//!
//! ```sh
//! cargo run --release --example flagship_tune                      # defaults
//! cargo run --release --example flagship_tune -- tau_acc=2.5 rest_noise=0.001
//! cargo run --release --example flagship_tune -- --f32             # single precision
//! cargo run --release --example flagship_tune -- --grid acc_noise=0.01,0.015,0.02
//! OFFLINE=1 cargo run --release --example flagship_tune     # forward-backward smoother
//! TRACE=1 cargo run --release --example flagship_tune       # bias every 10 s per trial
//! ```
//! The data folder is `$ROOTFUSE_BROAD_DIR` or `../shared/broad_csv`.
use rootfuse::attitude::filters::{Params, SqrtEskf, SqrtEskfParams};
use rootfuse::attitude::{ImuSample, Mask, OrientationFilter, Quat, Recording, Vec3};
use rootfuse::eval::metrics::{Alignment, evaluate};
use rootfuse::io::read_dir;
use std::path::PathBuf;

#[path = "shared/broad.rs"]
mod broad;

fn run<T: rootfuse::Lane>(
    p: &SqrtEskfParams,
    rec: &Recording,
    conv: impl Fn(f64) -> T,
    back: impl Fn(T) -> f64,
) -> (Vec<Quat<f64>>, Vec<Quat<f64>>) {
    let mut f = SqrtEskf::<T>::new(p);
    let v = |x: Vec3<f64>| Vec3::new(conv(x.x), conv(x.y), conv(x.z));
    let q64 = |q: Quat<T>| Quat::new(back(q.w), back(q.x), back(q.y), back(q.z));
    let mut q9 = Vec::with_capacity(rec.len());
    let mut q6 = Vec::with_capacity(rec.len());
    let trace = std::env::var_os("TRACE").is_some();
    for i in 0..rec.len() {
        let s = rec.sample(i);
        f.update(
            &ImuSample::new(v(s.gyr), v(s.acc), v(s.mag)),
            conv(rec.dt(i)),
        );
        if trace && i % 2857 == 0 {
            let b = f.bias();
            let d = |x: T| back(x).to_degrees();
            println!(
                "{} t={:6.1} bias {:+.3} {:+.3} {:+.3} deg/s rest={}",
                rec.name,
                i as f64 * rec.dt(i.max(1)),
                d(b.x),
                d(b.y),
                d(b.z),
                f.rest_detected().unwrap().any()
            );
        }
        q9.push(q64(f.quat9()));
        q6.push(q64(f.quat6()));
    }
    (q9, q6)
}

/// Total RMSE (degrees) 9D and 6D, and inclination RMSE, per trial.
fn score(p: &SqrtEskfParams, recs: &[Recording], f32: bool) -> Vec<[f64; 3]> {
    std::thread::scope(|scope| {
        let handles: Vec<_> = recs
            .iter()
            .map(|rec| {
                scope.spawn(move || {
                    if std::env::var_os("OFFLINE").is_some() {
                        return broad::smoothed(p, rec);
                    }
                    let (q9, q6) = if f32 {
                        run::<f32>(p, rec, |x| x as f32, f64::from)
                    } else {
                        run::<f64>(p, rec, |x| x, |x| x)
                    };
                    let (e9, incl) = evaluate(rec, &q9, Alignment::NineD)
                        .map_or((f64::NAN, f64::NAN), |r| (r.total, r.inclination));
                    let e6 = evaluate(rec, &q6, Alignment::SixD).map_or(f64::NAN, |r| r.total);
                    [e9, e6, incl]
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or([f64::NAN; 3]))
            .collect()
    })
}

fn print_row(label: &str, s: &[[f64; 3]], vqf: &[[f64; 3]]) {
    let mean =
        |rows: &[[f64; 3]], d: usize| rows.iter().map(|x| x[d]).sum::<f64>() / rows.len() as f64;
    let cells = |d: usize| {
        s.iter()
            .zip(vqf)
            .map(|(x, v)| format!("{:.3}{}", x[d], if x[d] < v[d] { "" } else { "!" }))
            .collect::<Vec<_>>()
            .join(" ")
    };
    // The objective of examples/flagship_cv.rs: mean over trials of the three ratios to VQF.
    let objective = s
        .iter()
        .zip(vqf)
        .map(|(x, v)| (0..3).map(|d| x[d] / v[d]).sum::<f64>() / 3.0)
        .sum::<f64>()
        / s.len() as f64;
    println!(
        "{label}: 9D {} mean {:.3} | 6D {} mean {:.3} | incl {} mean {:.3} | objective {objective:.4}",
        cells(0),
        mean(s, 0),
        cells(1),
        mean(s, 1),
        cells(2),
        mean(s, 2),
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::var_os("ROOTFUSE_BROAD_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/broad_csv"));
    let recs: Vec<Recording> = read_dir(&dir)?;

    let mut p = SqrtEskfParams::default();
    let mut f32 = false;
    let mut grid: Option<(String, Vec<f64>)> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--f32" {
            f32 = true;
        } else if a == "--grid" {
            let g = args.next().ok_or("--grid needs name=v1,v2,...")?;
            let (name, values) = g.split_once('=').ok_or("--grid needs name=v1,v2,...")?;
            let values = values
                .split(',')
                .map(str::parse)
                .collect::<Result<Vec<f64>, _>>()?;
            grid = Some((name.to_string(), values));
        } else {
            p.apply(&a)?;
        }
    }
    let vqf: Vec<[f64; 3]> = recs
        .iter()
        .map(|r| broad::vqf_online(&r.name))
        .collect::<Result<_, _>>()?;
    print_row("VQF online", &vqf, &vqf);
    match grid {
        None => print_row("ours", &score(&p, &recs, f32), &vqf),
        Some((name, values)) => {
            for v in values {
                let mut q = p.clone();
                q.set(&name, v)?;
                print_row(&format!("{name}={v}"), &score(&q, &recs, f32), &vqf);
            }
        }
    }
    Ok(())
}
