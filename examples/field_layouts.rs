//! The flagship's 9D heading where a lasting field disturbance comes and goes: mean online 9D
//! total RMSE (degrees) and 95 % coverage of the total error over seeds, on the simulated
//! pendulum, vehicle and handheld translation with a room-fixed 30 µT disturbance laid out
//! in time four ways, and on the simulator's disturbed scenarios (docs/accuracy.md, "A
//! field that returns"). The layouts are the cases one `mag_azimuth_tau` cannot serve at once:
//! a disturbance that ends (its field should not become north), a recording that starts
//! inside one (its first field is the wrong north), and one that starts inside and returns.
//!
//! ```sh
//! cargo run --release --example field_layouts                      # defaults
//! cargo run --release --example field_layouts -- mag_azimuth_tau=120 --seeds 3
//! cargo run --release --example field_layouts -- --seconds 600   # the scenarios' longer runs
//! ```
use rootfuse::attitude::filters::{SqrtEskf, SqrtEskfParams};
use rootfuse::attitude::{OrientationFilter, Quat, Recording, Vec3};
use rootfuse::eval::consistency::{UpperTriangle, consistency, upper_triangle};
use rootfuse::eval::metrics::{Alignment, evaluate};
use rootfuse::eval::sim::{Frame, MagDisturbance, scenario_simulation};

#[path = "shared/param_row.rs"]
mod param_row;

/// Disturbance episodes as (start, end) in seconds, and the run's length.
struct Layout {
    name: &'static str,
    seconds: f64,
    episodes: &'static [(f64, f64)],
}

const LAYOUTS: [Layout; 4] = [
    Layout {
        name: "600 s, 120 s from 60 s",
        seconds: 600.0,
        episodes: &[(60.0, 180.0)],
    },
    Layout {
        name: "600 s, 300 s from 60 s",
        seconds: 600.0,
        episodes: &[(60.0, 360.0)],
    },
    Layout {
        name: "300 s, starts inside 60 s",
        seconds: 300.0,
        episodes: &[(-10.0, 60.0)],
    },
    Layout {
        name: "600 s, starts inside 60 s, back at 300 s",
        seconds: 600.0,
        episodes: &[(-10.0, 60.0), (300.0, 420.0)],
    },
];

/// Online 9D total RMSE (degrees) and coverage of the total error.
fn score(p: &SqrtEskfParams, rec: &Recording) -> Result<[f64; 2], Box<dyn std::error::Error>> {
    let mut f = SqrtEskf::<f64>::new(p);
    let mut q: Vec<Quat<f64>> = Vec::with_capacity(rec.len());
    let mut cov: Vec<UpperTriangle> = Vec::with_capacity(rec.len());
    for i in 0..rec.len() {
        f.update(&rec.sample(i), rec.dt(i));
        q.push(f.quat());
        cov.push(upper_triangle(
            &f.attitude_covariance().ok_or("a covariance")?,
        ));
    }
    let truth = rec.truth.as_ref().ok_or("truth")?;
    let c = consistency(&q, &cov, truth, None, Alignment::NineD, 0.0, 0.1)?;
    Ok([evaluate(rec, &q, Alignment::NineD)?.total, c.coverage_total])
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = param_row::parse(5, 300.0)?;
    let (p, seeds, seconds) = (&args.params, args.seeds, args.seconds);
    let mut header = Vec::new();
    let mut cells = Vec::new();
    let mut cell = |name: String,
                    recs: &dyn Fn(u64) -> Result<Recording, Box<dyn std::error::Error>>|
     -> Result<(), Box<dyn std::error::Error>> {
        let mut sum = [0.0; 2];
        for seed in 0..seeds {
            let [e, c] = score(p, &recs(seed)?)?;
            sum[0] += e / seeds as f64;
            sum[1] += c / seeds as f64;
        }
        header.push(name);
        cells.push(format!("{:.2} / {:.3}", sum[0], sum[1]));
        Ok(())
    };
    for layout in &LAYOUTS {
        cell(layout.name.to_string(), &|seed| {
            // The three motions in turn, the disturbance's direction from the seed.
            let base = ["pendulum", "vehicle", "handheld-translation"][(seed % 3) as usize];
            let mut sim = scenario_simulation(base, seed, layout.seconds, 100.0)?;
            let a = 2.4 * seed as f64;
            let field = Vec3::new(a.cos(), a.sin(), -0.5) * (30.0 / 1.25_f64.sqrt());
            if let Some(m) = &mut sim.sensor.mag {
                m.disturbances = layout
                    .episodes
                    .iter()
                    .map(|&(start_s, end_s)| MagDisturbance {
                        start_s,
                        end_s,
                        field,
                        frame: Frame::Earth,
                        ramp_s: 1.0,
                    })
                    .collect();
            }
            Ok(sim.run()?.recording)
        })?;
    }
    for name in [
        "pendulum-disturbed",
        "handheld-translation-disturbed",
        "magnetic-disturbance",
        "vehicle-disturbed",
    ] {
        for seconds in [120.0, seconds] {
            cell(format!("{name} {seconds} s"), &|seed| {
                Ok(scenario_simulation(name, seed, seconds, 100.0)?
                    .run()?
                    .recording)
            })?;
        }
    }
    param_row::print_row(&args.label, &header, &cells);
    Ok(())
}
