//! MCAP logging of rollouts: schema, writer, reader.
