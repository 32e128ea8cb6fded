//! The fleet runner: devices streamed in blocks of rows, in any interleaving and with any
//! block boundaries, equal `run_recordings` per device bit for bit (orientation, bias, flags,
//! rejection counts); bad time stamps are refused or drop only their device.
use rootfuse::batch::{
    Columns, FleetBlock, FleetError, FleetRunner, OnError, Precision, run_recordings_with,
};
use rootfuse_attitude::Recording;
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_eval::sim::scenario;

/// The fleet's rows in `order` (pairs of device, row), cut into blocks at `cuts`.
fn blocks(recs: &[Recording], order: &[(usize, usize)], cuts: &[usize]) -> Vec<FleetBlock> {
    let mut out = Vec::new();
    let mut start = 0;
    for &end in cuts.iter().chain(std::iter::once(&order.len())) {
        let rows = &order[start..end.min(order.len())];
        start = end.min(order.len());
        if rows.is_empty() {
            continue;
        }
        out.push(FleetBlock {
            device: rows.iter().map(|&(d, _)| d as u32).collect(),
            t: rows.iter().map(|&(d, k)| recs[d].t[k]).collect(),
            gyr: rows.iter().map(|&(d, k)| recs[d].gyr[k]).collect(),
            acc: rows.iter().map(|&(d, k)| recs[d].acc[k]).collect(),
            mag: Some(
                rows.iter()
                    .map(|&(d, k)| recs[d].mag.as_ref().unwrap()[k])
                    .collect(),
            ),
        });
    }
    out
}

fn fleet() -> Vec<Recording> {
    // Ragged lengths and two rates; 6 devices fill one f64x4 chunk and part of another.
    (0..6)
        .map(|d| {
            let name = if d % 2 == 0 {
                "slow-rotation"
            } else {
                "static"
            };
            scenario(
                name,
                d as u64,
                1.0 + 0.3 * d as f64,
                50.0 + 25.0 * (d % 3) as f64,
            )
            .unwrap()
        })
        .collect()
}

fn check(order: &[(usize, usize)], cuts: &[usize], precision: Precision, what: &str) {
    let recs = fleet();
    let spec = FilterSpec::new("sqrt-eskf").unwrap();
    let columns = Columns {
        bias: true,
        covariance: true,
        flags: true,
    };
    let expected = run_recordings_with(&spec, &recs, precision, columns);
    let mut runner = FleetRunner::new(&spec, precision, columns);
    let blocks = blocks(&recs, order, cuts);
    let mut got: Vec<Vec<[u64; 4]>> = vec![Vec::new(); recs.len()];
    let mut flags: Vec<Vec<u8>> = vec![Vec::new(); recs.len()];
    for (i, b) in blocks.iter().enumerate() {
        let est = runner.step(b, blocks.get(i + 1), OnError::Stop).unwrap();
        assert!(est.kept.iter().all(|&k| k));
        for r in 0..b.len() {
            let d = b.device[r] as usize;
            got[d].push(est.quat[r].to_array().map(f64::to_bits));
            flags[d].push(est.flags[r]);
            let k = got[d].len() - 1;
            assert_eq!(est.bias[r], expected[d].bias[k], "{what}: bias {d} {k}");
            assert_eq!(
                est.covariance[r], expected[d].covariance[k],
                "{what}: cov {d} {k}"
            );
        }
    }
    for (d, e) in expected.iter().enumerate() {
        let want: Vec<[u64; 4]> = e
            .quat
            .iter()
            .map(|q| q.to_array().map(f64::to_bits))
            .collect();
        assert_eq!(got[d], want, "{what}: device {d}");
        assert_eq!(flags[d], e.flags, "{what}: flags of device {d}");
        assert_eq!(
            runner.rejections(d as u32),
            e.rejections,
            "{what}: rejections {d}"
        );
    }
}

/// Time-major, device-major and shuffled-run orders, with blocks of many sizes, including
/// blocks that hold a device's first row alone (its first step then comes from the next
/// block).
#[test]
fn any_order_and_blocks_equal_whole_recordings() {
    let recs = fleet();
    let lens: Vec<usize> = recs.iter().map(Recording::len).collect();
    let lens = &lens;
    let longest = recs.iter().map(Recording::len).max().unwrap();
    let time_major: Vec<(usize, usize)> = (0..longest)
        .flat_map(|k| {
            (0..recs.len())
                .filter(move |&d| k < lens[d])
                .map(move |d| (d, k))
        })
        .collect();
    let device_major: Vec<(usize, usize)> = (0..recs.len())
        .flat_map(|d| (0..lens[d]).map(move |k| (d, k)))
        .collect();
    // Runs of 7 rows per device in turn.
    let mut runs = Vec::new();
    let mut next = vec![0usize; recs.len()];
    while next.iter().zip(&recs).any(|(&n, r)| n < r.len()) {
        for d in 0..recs.len() {
            for _ in 0..7 {
                if next[d] < recs[d].len() {
                    runs.push((d, next[d]));
                    next[d] += 1;
                }
            }
        }
    }
    let n = time_major.len();
    let every = |step: usize| {
        (1..)
            .map(|i| i * step)
            .take_while(|&c| c < n)
            .collect::<Vec<_>>()
    };
    for precision in [Precision::F64, Precision::F32] {
        check(&time_major, &[], precision, "time-major, one block");
        // One step of every device per block. (Not one row per block: a device's second row
        // must be in its first row's block or the next one, see `FleetRunner`.)
        check(
            &time_major,
            &every(6),
            precision,
            "time-major, 6 rows per block",
        );
        check(&time_major, &every(13), precision, "time-major, 13 rows");
        check(
            &device_major,
            &every(50),
            precision,
            "device-major, 50 rows",
        );
        check(&runs, &every(97), precision, "runs of 7, 97 rows");
        // Device 1's first row alone at the end of a block: cut right after it.
        let first_of_1 = runs.iter().position(|&(d, _)| d == 1).unwrap();
        check(&runs, &[first_of_1 + 1], precision, "first row alone");
    }
}

/// A time stamp that goes back: `Stop` refuses the block (nothing of it runs, and the next
/// good block continues as if it had not come), `DropDevice` leaves only that device out.
#[test]
fn bad_time_stops_or_drops_only_its_device() {
    let recs = fleet();
    let spec = FilterSpec::new("mahony").unwrap();
    let order: Vec<(usize, usize)> = (0..40).flat_map(|k| (0..3).map(move |d| (d, k))).collect();
    let mut bs = blocks(&recs, &order, &[30, 60]);
    bs[1].t[4] = bs[1].t[1]; // device 1, earlier than its previous row
    let mut runner = FleetRunner::new(&spec, Precision::F64, Columns::default());
    runner.step(&bs[0], None, OnError::Stop).unwrap();
    let err = runner.step(&bs[1], None, OnError::Stop).unwrap_err();
    assert!(
        matches!(
            err,
            FleetError::TimeNotIncreasing {
                row: 4,
                device: 1,
                ..
            }
        ),
        "{err:?}"
    );
    let mut dropping = FleetRunner::new(&spec, Precision::F64, Columns::default());
    dropping.step(&bs[0], None, OnError::DropDevice).unwrap();
    let est = dropping.step(&bs[1], None, OnError::DropDevice).unwrap();
    assert_eq!(est.failures.len(), 1);
    let kept_1: Vec<bool> = (0..bs[1].len())
        .filter(|&r| bs[1].device[r] == 1)
        .map(|r| est.kept[r])
        .collect();
    assert_eq!(
        kept_1,
        [
            true, false, false, false, false, false, false, false, false, false
        ]
    );
    assert!(
        (0..bs[1].len())
            .filter(|&r| bs[1].device[r] != 1)
            .all(|r| est.kept[r])
    );
    let est = dropping.step(&bs[2], None, OnError::DropDevice).unwrap();
    assert!((0..bs[2].len()).all(|r| est.kept[r] == (bs[2].device[r] != 1)));
    assert!(est.failures.is_empty());
    let mut nan = bs[2].clone();
    nan.t[0] = f64::NAN;
    assert!(matches!(
        runner.step(&nan, None, OnError::Stop),
        Err(FleetError::TimeNotFinite {
            row: 0,
            device: 0,
            ..
        })
    ));
}
