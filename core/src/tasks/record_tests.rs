//! Every record the tasks declare is sound: a valid format, one column per field, each
//! field's type the one its conversion reads.

use crate::logfmt::{EncodeError, LogFormat, LogRecord};

fn check<R: LogRecord + Default>() -> (LogFormat, Result<(), EncodeError>) {
    (R::FORMAT, R::check())
}

#[test]
fn every_task_record_is_a_sound_declaration() {
    let records = [
        check::<super::estimator::EstimatorStateLog>(),
        check::<super::estimator::EstimatorHealthLog>(),
        check::<super::estimator::EstimatorSdLog>(),
        check::<super::imu::ImuFastLog>(),
        check::<super::imu::ImuSlowLog>(),
        check::<super::device_status::DeviceStatusRecord>(),
        check::<super::gps::GpsFixLog>(),
        check::<super::watchdog::WatchdogLog>(),
        check::<super::health::TaskHealthLog>(),
        check::<super::servo::ServoPilotLog>(),
        check::<super::servo::ServoCommandLog>(),
        check::<super::control::ControlLog>(),
        check::<super::control::ControlGainsLog>(),
        check::<crate::link::counters::LinkCounters>(),
    ];
    for (format, result) in records {
        assert_eq!(result, Ok(()), "{format:?}");
    }
}

#[test]
fn the_gains_record_has_a_column_for_each_control_parameter_in_order() {
    use super::control::{ControlGainsLog, ControlSettings, define_params};
    use crate::link::params::ParamTable;
    let mut table = ParamTable::new();
    define_params(&mut table, &ControlSettings::default()).expect("defines");
    let names: heapless::Vec<&str, 32> = table
        .iter()
        .filter_map(|p| p.name().as_str().strip_prefix("control."))
        // The one name that differs: the column spells its unit as conventions.md does, the
        // parameter kept the name researchers' scripts already set.
        .map(|name| {
            if name == "cruise_mps" {
                "cruise_m_s"
            } else {
                name
            }
        })
        .collect();
    let columns: heapless::Vec<&str, 32> = ControlGainsLog::FORMAT.columns.split(',').collect();
    assert_eq!(names, columns);
}
