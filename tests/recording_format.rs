//! Recording format v1: round trips and a bounded fuzz of the reader.

use proptest::prelude::*;
use servosight::signal::channel::plausible_range_of;
use servosight::signal::{Recording, RecordingReader, write_recording_to};

fn column_name() -> impl Strategy<Value = String> {
    prop_oneof![
        "[A-Za-z][A-Za-z0-9_.#]{0,12}",
        Just("ref.X.straightness_h_um#3".to_string()),
        "[a-z]{1,4},[a-z]{1,4}", // a comma inside a name must survive (quoted)
    ]
}

fn recording() -> impl Strategy<Value = Recording> {
    (
        proptest::collection::hash_set(column_name(), 0..6),
        0usize..30,
    )
        .prop_flat_map(|(names, rows)| {
            let names: Vec<String> = names.into_iter().filter(|n| n != "time_s").collect();
            let width = names.len();
            (
                Just(names),
                proptest::collection::vec(0.0f64..1.0e3, rows),
                proptest::collection::vec(
                    proptest::num::f64::NORMAL | proptest::num::f64::ZERO,
                    rows * width,
                ),
                proptest::collection::vec(("[a-z]{1,8}", "[ -~]{0,20}"), 0..3),
            )
                .prop_map(move |(names, steps, values, metadata)| {
                    let mut all = vec!["time_s".to_string()];
                    all.extend(names.iter().cloned());
                    let mut rec = Recording::new("prop", all).unwrap();
                    for (k, v) in metadata {
                        rec.set_metadata(&k, &v);
                    }
                    // A column the format knows (the reference straightness) takes values in
                    // its plausible range; the rest any normal number.
                    let ranges: Vec<Option<(f64, f64)>> =
                        names.iter().map(|n| plausible_range_of(n)).collect();
                    let mut t = 0.0;
                    for (r, step) in steps.iter().enumerate() {
                        t += step;
                        let mut row = vec![t];
                        row.extend(
                            values[r * width..(r + 1) * width].iter().zip(&ranges).map(
                                |(&v, range)| range.map_or(v, |(low, high)| v.clamp(low, high)),
                            ),
                        );
                        rec.push_row(&row).unwrap();
                    }
                    rec
                })
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn written_recordings_read_back_bit_for_bit(rec in recording()) {
        let bytes = write_recording_to(Vec::new(), &rec).unwrap();
        let back = RecordingReader::from_reader(bytes.as_slice(), "prop").unwrap().read_to_end().unwrap();
        prop_assert_eq!(back.names(), rec.names());
        prop_assert_eq!(back.metadata(), rec.metadata());
        for i in 0..rec.names().len() {
            let (a, b) = (rec.column_at(i), back.column_at(i));
            prop_assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }

    /// Arbitrary bytes never panic the reader: every input is either a recording or an error
    /// with a location.
    #[test]
    fn arbitrary_bytes_never_panic_the_reader(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        if let Ok(reader) = RecordingReader::from_reader(bytes.as_slice(), "fuzz") {
            let (_, error) = reader.read_until_error();
            if let Some(e) = error {
                prop_assert!(e.to_string().starts_with("fuzz"));
            }
        }
    }

    /// Values outside a known channel's plausible range are refused with their location.
    #[test]
    fn implausible_values_of_known_channels_are_refused(v in 1.0e6f64..1.0e300) {
        let text = format!("time_s,X.torque_Nm\n0,1\n1,{v}\n");
        let err = RecordingReader::from_reader(text.as_bytes(), "r").unwrap().read_to_end().unwrap_err();
        prop_assert!(err.to_string().contains("line 3, column 2 (`X.torque_Nm`)"), "{}", err);
    }

    /// Valid files with one byte changed, inserted or removed: no panic, and an error always
    /// names the file and a line.
    #[test]
    fn mutated_recordings_fail_cleanly(rec in recording(), at in any::<prop::sample::Index>(), byte in any::<u8>(), kind in 0u8..3) {
        let mut bytes = write_recording_to(Vec::new(), &rec).unwrap();
        if !bytes.is_empty() {
            let i = at.index(bytes.len());
            match kind {
                0 => bytes[i] = byte,
                1 => bytes.insert(i, byte),
                _ => { bytes.remove(i); }
            }
        }
        match RecordingReader::from_reader(bytes.as_slice(), "mutant") {
            Ok(reader) => {
                if let (_, Some(e)) = reader.read_until_error() {
                    let text = e.to_string();
                    prop_assert!(text.starts_with("mutant"), "{}", text);
                }
            }
            Err(e) => prop_assert!(e.to_string().starts_with("mutant")),
        }
    }
}
