//! The filter choice shared by the commands that run one (`run`, `throughput`): name,
//! `key=value` overrides, 6D/9D and the gap limit, resolved into one [`FilterSpec`].
use clap::Args;
use rootfuse_attitude::registry::{Assignment, FilterSpec};

/// Which filter, with which parameters.
#[derive(Args, Debug)]
pub struct FilterArgs {
    /// Filter name (see `rootfuse filters`); the flagship (`sqrt-eskf`) unless given.
    #[arg(long, default_value = "flagship")]
    pub filter: String,
    /// Parameter override `key=value` (repeatable, each parameter once; `rootfuse filters`
    /// lists them with units, ranges and kinds: a whole number or a switch refuses fractions).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// 6: gravity only; 9: with magnetometer (every filter but `gyro`, which never reads the
    /// magnetometer: there it is an error). The same as `--param dof=6|9`: give one of them.
    #[arg(long, value_parser = ["6", "9"])]
    pub dof: Option<String>,
    /// Longest accepted time step, s: a sample after a longer gap is skipped (flag 1) and the
    /// orientation held across it. The same as `--param max_dt=SECONDS` (default 1): give
    /// one of them.
    #[arg(long, value_name = "SECONDS")]
    pub max_dt: Option<f64>,
}

impl FilterArgs {
    /// The spec, or one line saying what is wrong with the options. Each parameter is given
    /// once: `--dof` and `--param dof=…`, `--max-dt` and `--param max_dt=…`, or one `--param`
    /// twice are an error naming both, never a silent last-one-wins.
    pub fn spec(&self) -> Result<FilterSpec, String> {
        let mut spec = FilterSpec::new(&self.filter).map_err(|e| e.to_string())?;
        spec.set_all(&self.assignments())
            .map_err(|e| e.to_string())?;
        Ok(spec)
    }

    /// Every parameter the command line sets, named as the user wrote it: the dedicated
    /// options first, then `--param` in order.
    pub fn assignments(&self) -> Vec<Assignment> {
        let mut all = Vec::with_capacity(self.params.len() + 2);
        if let Some(dof) = &self.dof {
            all.push(Assignment::from_source(
                format!("dof={dof}"),
                format!("--dof {dof}"),
            ));
        }
        if let Some(max_dt) = self.max_dt {
            all.push(Assignment::from_source(
                format!("max_dt={max_dt}"),
                format!("--max-dt {max_dt}"),
            ));
        }
        all.extend(
            self.params
                .iter()
                .map(|p| Assignment::from_source(p.as_str(), format!("--param {p}"))),
        );
        all
    }

    /// True when `--dof` or `--param dof=…` asked for 6D/9D explicitly (rather than the
    /// filter's default).
    pub fn dof_explicit(&self) -> bool {
        self.dof.is_some() || self.param_given("dof")
    }

    fn param_given(&self, name: &str) -> bool {
        self.params
            .iter()
            .any(|p| p.split_once('=').is_some_and(|(k, _)| k.trim() == name))
    }
}
