#pragma once
// Raw hammer-test time data in a MATLAB .mat file (v5 or v7.3), read and written with matio.
// The layout is documented in measurements/README.md ("Raw hammer time data"):
//
// | variable            | size                     | meaning                                        |
// |---------------------|--------------------------|------------------------------------------------|
// | sample_rate_hz      | 1 x 1                    | sample rate, Hz                                |
// | force               | Ns x Nhits x Nin         | hammer force records, N                        |
// | response            | Ns x Nout x Nhits x Nin  | response records, SI (m/s^2, m/s or m)         |
// | response_quantity   | char                     | "acceleration", "velocity" or "displacement"   |
// | output_names        | cell of char, optional   | Nout names (default out1, out2, ...)           |
// | input_names         | cell of char, optional   | Nin names (default in1, in2, ...)              |
// | response_full_scale | Nout x 1 or 1 x 1, opt.  | full-scale range per output, SI                |
// | force_full_scale_n  | Nin x 1 or 1 x 1, opt.   | full-scale range of the force channel, N       |
// | sensor_body, sensor_position (Nout x 3), sensor_direction (Nout x 3), impact_body,          |
// | impact_position (Nin x 3), impact_direction (Nin x 3), frame_origin (1 x 3): as in the      |
// | measurement .mat of SPEC §3, optional, but each side (sensor / impact) all or nothing.      |
//
// Trailing singleton dimensions may be dropped (MATLAB does): with one input the force is
// Ns x Nhits and the response Ns x Nout x Nhits. Numeric variables may be double, single or integer.

#include <filesystem>

#include "stagefit/measurement/hammer_estimation.h"
#include "stagefit/measurement/mat_file.h"

namespace stagefit::measurement {

/// Reads raw hammer time data and validates it (Validate(const RawHammerData&)): sizes consistent,
/// no NaN/Inf, no empty record, no dead channel, no all-zero force, sizes within
/// kMaxRawSamplesPerRecord / kMaxRawSamplesTotal (checked from the header before the data are
/// read). data.source = path. Throws InputError naming the file, the variable and what was expected
/// (e.g. "'raw.mat': response: size 4096 x 12 x 5, expected Ns x Nout x Nhits x Nin = 4096 x 12 x
/// 5 x 10").
RawHammerData ReadRawHammerFile(const std::filesystem::path& path);

/// Writes `data` in the layout above (v5: zlib-compressed; v7.3 needs IsMatV73Supported()), atomically: to a temporary file beside
/// `path`, renamed over it when complete. Every input must have the same number of hits; a side's
/// geometry is written only when every channel of that side has one (a mix throws). Throws
/// InputError when the data are invalid or the file cannot be written.
void WriteRawHammerFile(const std::filesystem::path& path, const RawHammerData& data,
                        MatVersion version = MatVersion::kV5);

}  // namespace stagefit::measurement
