"""The explicit time step: phases in order (USL or MUSL), buffers, migration and regrouping."""
