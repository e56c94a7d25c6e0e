//! Signals: channel names and units, the columnar [`Recording`], and recording format v1 (CSV).

pub mod channel;
pub mod csv_format;
pub mod error;
pub mod pieces;
pub mod recording;

pub use channel::{AxisId, Channel, Quantity, axis_column, reference_column};
pub use csv_format::{
    AVERAGED_OVER_S, RecordingReader, RecordingWriter, RowSource, read_recording, write_recording,
    write_recording_to,
};
pub use error::{Location, RecordingError, Separator};
pub use pieces::{
    ReadProgress, RecordingPieces, group_pieces, later_pieces, piece_path, pieces_left_out,
    read_pieces, with_later_pieces,
};
pub use recording::{Recording, Schema};
