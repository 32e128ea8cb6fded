//! Cross-validated tuning of the flagship `sqrt-eskf` on the BROAD trials: scores a fixed
//! design of candidate parameter sets (the defaults plus a Latin-hypercube sample, log-uniform
//! around the defaults, seeded) on every trial once, then
//!
//! The design is the product of a Latin hypercube over the 6D parameters and one over the
//! magnetic ones (which only move the 9D heading), 6 magnetic sets by default.
//!
//! * **in sample**: the candidate minimising the objective over all trials, scored on them;
//! * **leave one trial out**: for each trial, the candidate minimising the objective over the
//!   other trials, scored on the held-out one (the candidate set does not depend on the scores,
//!   so the held-out trial never influences its own choice).
//!
//! The objective is the mean over trials of `(9D/VQF₉ + 6D/VQF₆ + incl/VQF_incl)/3` (total RMSE
//! ratios against VQF online, and the inclination ratio): a mean of ratios, so no trial's scale
//! dominates and one bad trial does not decide alone.
//!
//! ```sh
//! cargo run --release --example flagship_cv                 # 128 candidates, table
//! cargo run --release --example flagship_cv -- --candidates 256 --seed 7
//! cargo run --release --example flagship_cv -- --offline    # also the smoother for the winner
//! cargo run --release --example flagship_cv -- tau_acc=1.5  # centre of the design
//! ```
//! Per-trial scores of every candidate are written to `target/flagship_cv_scores.csv`. The data
//! folder is `$ROOTFUSE_BROAD_DIR` or `../shared/broad_csv`; the VQF numbers are those of its
//! README (14 trials).
use indicatif::{ProgressBar, ProgressStyle};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rootfuse::attitude::filters::{LaneParams, Params, SqrtEskf, SqrtEskfParams};
use rootfuse::attitude::{ImuSample, OrientationFilter, Quat, Recording, Vec3};
use rootfuse::eval::metrics::{Alignment, evaluate};
use rootfuse::io::read_dir;
use rootfuse::lane::wide::f64x4;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

#[path = "shared/broad.rs"]
mod broad;

/// The tuned parameters of the 6D part (gravity, gyro, bias, rest) and their factor ranges
/// (log-uniform, `[1/f, f]` around the centre). They decide the 6D estimate and the
/// inclination alone; the magnetic part below only moves the 9D heading offset, which is why
/// the design is a product of the two (every 6D set with every magnetic set).
const DESIGN_6D: [(&str, f64); 10] = [
    ("acc_noise", 3.0),
    ("tau_acc", 2.5),
    ("gyr_noise", 3.0),
    ("bias_walk", 10.0),
    ("acc_gate", 1.6),
    ("rest_gyr", 2.0),
    ("rest_acc", 2.0),
    ("rest_time", 2.0),
    ("rest_noise", 3.0),
    ("bias_step_gate", 2.0),
];

/// The tuned parameters of the magnetic heading offset (9D only) and their factor ranges.
const DESIGN_MAG: [(&str, f64); 5] = [
    ("mag_noise", 3.0),
    ("heading_walk", 5.0),
    ("heading_rate_noise", 5.0),
    ("mag_norm_th", 2.0),
    ("mag_dip_th", 2.0),
];

/// Scores `[9D total, 6D total, inclination]` (degrees) of one trial.
type Score = [f64; 3];

/// Latin hypercube: `n` sets, each parameter's range cut into `n` strata visited once in a
/// random order, a uniform point (in log space) inside each stratum.
fn design(
    centre: &SqrtEskfParams,
    names: &[(&str, f64)],
    n: usize,
    seed: u64,
) -> Vec<SqrtEskfParams> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut sets = vec![centre.clone(); n];
    for &(name, factor) in names {
        let c = centre.get(name).expect("a parameter of SqrtEskfParams");
        let mut strata: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            strata.swap(i, rng.random_range(0..=i));
        }
        for (set, k) in sets.iter_mut().zip(strata) {
            let u = (k as f64 + rng.random::<f64>()) / n as f64;
            let v = c * factor.powf(2.0 * u - 1.0);
            set.set(name, v).expect("inside the parameter's range");
        }
    }
    sets
}

/// Runs four candidate sets in the four lanes of an `f64x4` filter over one recording.
fn score4(sets: &[SqrtEskfParams; 4], rec: &Recording) -> [Score; 4] {
    let lanes =
        LaneParams::per_lane(sets).expect("four valid sets that differ only in real parameters");
    let mut f = SqrtEskf::<f64x4>::with_lane_params(&lanes);
    let v = |x: Vec3<f64>| Vec3::<f64x4>::from_f64([x.x, x.y, x.z]);
    let mut q9: [Vec<Quat<f64>>; 4] = std::array::from_fn(|_| Vec::with_capacity(rec.len()));
    let mut q6: [Vec<Quat<f64>>; 4] = std::array::from_fn(|_| Vec::with_capacity(rec.len()));
    for i in 0..rec.len() {
        let s = rec.sample(i);
        f.update(
            &ImuSample::new(v(s.gyr), v(s.acc), v(s.mag)),
            f64x4::splat(rec.dt(i)),
        );
        let (a, b) = (f.quat9(), f.quat6());
        for l in 0..4 {
            q9[l].push(a.lane(l));
            q6[l].push(b.lane(l));
        }
    }
    std::array::from_fn(|l| evaluate_pair(rec, &q9[l], &q6[l]))
}

fn evaluate_pair(rec: &Recording, q9: &[Quat<f64>], q6: &[Quat<f64>]) -> Score {
    let (e9, incl) = evaluate(rec, q9, Alignment::NineD)
        .map_or((f64::NAN, f64::NAN), |r| (r.total, r.inclination));
    let e6 = evaluate(rec, q6, Alignment::SixD).map_or(f64::NAN, |r| r.total);
    [e9, e6, incl]
}

/// One set in `f32` (scalar), for the f32/f64 agreement check.
fn score_f32(p: &SqrtEskfParams, rec: &Recording) -> Score {
    let mut f = SqrtEskf::<f32>::new(p);
    let v = |x: Vec3<f64>| Vec3::<f32>::from_f64([x.x, x.y, x.z]);
    let q64 = |q: Quat<f32>| Quat::new(q.w.into(), q.x.into(), q.y.into(), q.z.into());
    let (mut q9, mut q6) = (Vec::new(), Vec::new());
    for i in 0..rec.len() {
        let s = rec.sample(i);
        f.update(
            &ImuSample::new(v(s.gyr), v(s.acc), v(s.mag)),
            rec.dt(i) as f32,
        );
        q9.push(q64(f.quat9()));
        q6.push(q64(f.quat6()));
    }
    evaluate_pair(rec, &q9, &q6)
}

/// Runs `job(i)` for `i in 0..n` on two threads, with a progress bar.
fn parallel<R: Send>(n: usize, label: &str, job: impl Fn(usize) -> R + Sync) -> Vec<R> {
    let bar = ProgressBar::new(n as u64).with_message(label.to_string());
    bar.set_style(
        ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} {elapsed} (eta {eta})")
            .expect("a valid template"),
    );
    let next = AtomicUsize::new(0);
    let mut out: Vec<(usize, R)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..2)
            .map(|_| {
                scope.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= n {
                            break mine;
                        }
                        mine.push((i, job(i)));
                        bar.inc(1);
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("worker"))
            .collect()
    });
    bar.finish_and_clear();
    out.sort_by_key(|(i, _)| *i);
    out.into_iter().map(|(_, r)| r).collect()
}

/// Objective of one candidate over a set of trials (mean ratio to VQF online).
fn objective(scores: &[Score], vqf: &[Score], trials: impl Iterator<Item = usize>) -> f64 {
    let (mut sum, mut n) = (0.0, 0.0);
    for t in trials {
        sum += (0..3).map(|d| scores[t][d] / vqf[t][d]).sum::<f64>() / 3.0;
        n += 1.0;
    }
    sum / n
}

fn argmin(scores: &[Vec<Score>], vqf: &[Score], trials: &[usize]) -> usize {
    (0..scores.len())
        .map(|c| (c, objective(&scores[c], vqf, trials.iter().copied())))
        .filter(|(_, j)| j.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0, |(c, _)| c)
}

fn mean(rows: &[Score], d: usize) -> f64 {
    rows.iter().map(|r| r[d]).sum::<f64>() / rows.len() as f64
}

fn cells(s: &Score) -> String {
    format!("{:.2} / {:.2} / {:.3}", s[0], s[1], s[2])
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::var_os("ROOTFUSE_BROAD_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/broad_csv"));
    let mut centre = SqrtEskfParams::default();
    let (mut n, mut seed, mut offline) = (128usize, 1u64, false);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--candidates" => n = args.next().ok_or("--candidates N")?.parse()?,
            "--seed" => seed = args.next().ok_or("--seed S")?.parse()?,
            "--offline" => offline = true,
            _ => centre.apply(&a)?,
        }
    }
    let recs: Vec<Recording> = read_dir(&dir)?;
    let vqf: Vec<Score> = recs
        .iter()
        .map(|r| broad::vqf_online(&r.name))
        .collect::<Result<_, _>>()?;
    // The product of `n6` 6D sets (the first the centre, the second the centre without
    // bias-step detection) and `n_mag` magnetic sets (the first the centre): candidate 0 is
    // the centre (the current defaults unless overridden).
    let n_mag = 6;
    let n6 = n.div_ceil(4 * n_mag) * 4;
    let mut six = vec![centre.clone(), centre.clone()];
    six[1].set("bias_step_gate", 0.0)?;
    six.extend(design(&centre, &DESIGN_6D, n6 - 2, seed));
    let mut mag = vec![centre.clone()];
    mag.extend(design(&centre, &DESIGN_MAG, n_mag - 1, seed + 1));
    let mut sets = Vec::with_capacity(n6 * n_mag);
    for m in &mag {
        for a in &six {
            let mut c = a.clone();
            for (name, _) in DESIGN_MAG {
                c.set(name, m.get(name).ok_or("a magnetic parameter")?)?;
            }
            sets.push(c);
        }
    }
    let n = sets.len();

    let jobs = (n / 4) * recs.len();
    let results = parallel(jobs, "candidates x trials", |j| {
        let (chunk, t) = (j / recs.len(), j % recs.len());
        let four: [SqrtEskfParams; 4] = std::array::from_fn(|l| sets[4 * chunk + l].clone());
        score4(&four, &recs[t])
    });
    // scores[candidate][trial]
    let mut scores = vec![vec![[f64::NAN; 3]; recs.len()]; n];
    for (j, four) in results.into_iter().enumerate() {
        let (chunk, t) = (j / recs.len(), j % recs.len());
        for (l, s) in four.into_iter().enumerate() {
            scores[4 * chunk + l][t] = s;
        }
    }
    write_scores(&sets, &scores, &recs)?;

    let all: Vec<usize> = (0..recs.len()).collect();
    let best = argmin(&scores, &vqf, &all);
    let cv: Vec<(usize, Score)> = (0..recs.len())
        .map(|held| {
            let others: Vec<usize> = all.iter().copied().filter(|&t| t != held).collect();
            let c = argmin(&scores, &vqf, &others);
            (c, scores[c][held])
        })
        .collect();
    let cv_rows: Vec<Score> = cv.iter().map(|(_, s)| *s).collect();
    let f32_rows = parallel(recs.len(), "f32 check", |t| {
        score_f32(&sets[best], &recs[t])
    });
    let offline_rows = if offline {
        Some(parallel(recs.len(), "smoother", |t| {
            broad::smoothed(&sets[best], &recs[t])
        }))
    } else {
        None
    };

    let j = |c: usize| objective(&scores[c], &vqf, all.iter().copied());
    println!(
        "{n} candidates (seed {seed}); objective (mean ratio to VQF online): centre {:.4}, in-sample best #{best} {:.4}",
        j(0),
        j(best)
    );
    println!(
        "\n| trial | VQF online 9D / 6D / incl | centre | in-sample (#{best}) | leave-one-out (candidate) |"
    );
    println!("|---|---|---|---|---|");
    for (t, rec) in recs.iter().enumerate() {
        println!(
            "| {} | {} | {} | {} | {} (#{}) |",
            rec.name,
            cells(&vqf[t]),
            cells(&scores[0][t]),
            cells(&scores[best][t]),
            cells(&cv[t].1),
            cv[t].0
        );
    }
    let m = |rows: &[Score]| [mean(rows, 0), mean(rows, 1), mean(rows, 2)];
    println!(
        "| **mean** | {} | {} | {} | {} |",
        cells(&m(&vqf)),
        cells(&m(&scores[0])),
        cells(&m(&scores[best])),
        cells(&m(&cv_rows))
    );
    let wins =
        |rows: &[Score], d: usize| (0..recs.len()).filter(|&t| rows[t][d] < vqf[t][d]).count();
    for (label, rows) in [
        ("centre", &scores[0]),
        ("in-sample", &scores[best]),
        ("leave-one-out", &cv_rows),
    ] {
        let incl_over = (0..recs.len())
            .map(|t| rows[t][2] / vqf[t][2])
            .fold(0.0, f64::max);
        println!(
            "{label}: better than VQF online on {}/14 (9D), {}/14 (6D), {}/14 (incl); worst incl ratio {:.2}",
            wins(rows, 0),
            wins(rows, 1),
            wins(rows, 2),
            incl_over
        );
    }
    let cv_over_in = (0..3)
        .map(|d| mean(&cv_rows, d) / mean(&scores[best], d))
        .collect::<Vec<_>>();
    println!(
        "leave-one-out mean / in-sample mean: 9D {:.3}, 6D {:.3}, incl {:.3}",
        cv_over_in[0], cv_over_in[1], cv_over_in[2]
    );
    let df32 = (0..recs.len())
        .flat_map(|t| (0..3).map(move |d| (t, d)))
        .map(|(t, d)| (f32_rows[t][d] - scores[best][t][d]).abs())
        .fold(0.0, f64::max);
    println!("in-sample best in f32: largest |f32 − f64| over the 42 cells {df32:.4}°");
    if let Some(rows) = offline_rows {
        println!("\n| trial | smoother 9D / 6D / incl (#{best}) |\n|---|---|");
        for (t, rec) in recs.iter().enumerate() {
            println!("| {} | {} |", rec.name, cells(&rows[t]));
        }
        println!("| **mean** | {} |", cells(&m(&rows)));
    }
    println!("\nin-sample best #{best}, differences from the centre:");
    for (name, _) in DESIGN_6D.iter().chain(&DESIGN_MAG) {
        let (a, b) = (centre.get(name), sets[best].get(name));
        if a != b {
            println!(
                "  {name}={:.6}   (centre {})",
                b.unwrap_or(f64::NAN),
                a.unwrap_or(f64::NAN)
            );
        }
    }
    Ok(())
}

/// `target/flagship_cv_scores.csv`: one line per candidate and trial, the parameters first.
/// Written to a temporary file and renamed, so a partial file is never left behind.
fn write_scores(
    sets: &[SqrtEskfParams],
    scores: &[Vec<Score>],
    recs: &[Recording],
) -> std::io::Result<()> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target");
    std::fs::create_dir_all(&dir)?;
    let tmp = dir.join("flagship_cv_scores.csv.tmp");
    let mut w = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
    let names: Vec<&str> = DESIGN_6D
        .iter()
        .chain(&DESIGN_MAG)
        .map(|(n, _)| *n)
        .collect();
    writeln!(
        w,
        "candidate,{},trial,rmse_9d,rmse_6d,incl",
        names.join(",")
    )?;
    for (c, set) in sets.iter().enumerate() {
        let values: Vec<String> = names
            .iter()
            .map(|n| set.get(n).map_or(String::new(), |v| format!("{v:e}")))
            .collect();
        for (t, rec) in recs.iter().enumerate() {
            let s = scores[c][t];
            writeln!(
                w,
                "{c},{},{},{},{},{}",
                values.join(","),
                rec.name,
                s[0],
                s[1],
                s[2]
            )?;
        }
    }
    w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
    std::fs::rename(tmp, dir.join("flagship_cv_scores.csv"))
}
