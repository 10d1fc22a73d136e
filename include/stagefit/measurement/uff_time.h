#pragma once
// Raw hammer-test time data as UFF 58 time records (function type 1), as acquisition systems export
// them: one record per channel per hit, each with the channel as its response DOF and the impact point
// as its reference DOF.
//
// Layout read (and written by ConvertRawHammerToUff):
//  - every record: function type 1, real ordinate, even abscissa (time: minimum 0, increment 1/fs);
//  - record 6: response node/direction = the channel, reference node/direction = the impact point of
//    the run, load case = the hit number (1, 2, ... within that impact);
//  - the force record of a hit is the one whose response DOF is the reference DOF (a hammer's force
//    is measured where it hits), or the channel named by UffTimeOptions::force_channel;
//  - channels are named "<node>+X" ... as in ConvertUffToFrfData, or by record 4 "channels: <name>";
//  - units: the ordinate's units label (N, lbf, kN for the force; g, m/s^2, mm/s^2, in/s^2, m/s, m, ...
//    for the responses, converted to SI, uff58.h) or SI when it names none.
// Inputs are the distinct reference DOFs in order of first appearance; hits follow the load case
// numbers. The response quantity follows the responses' units (or specific data type 8/11/12).

#include <string>
#include <vector>

#include "stagefit/measurement/hammer_estimation.h"
#include "stagefit/measurement/uff58.h"

namespace stagefit::measurement {

struct UffTimeOptions {
  /// The force channel's name ("1001-Y"); empty: in each hit the record whose response DOF is the
  /// reference DOF.
  std::string force_channel;
  /// The response channels to keep, by name; empty: every channel but the force.
  std::vector<std::string> responses;
};

/// Builds raw hammer data from the time records of a universal file. Throws InputError (naming
/// `source`, the record and the problem) when: there is no time record; a record is complex or has an
/// uneven abscissa; records differ in sample rate or length; a hit has no force record, or lacks a
/// response channel the others have; a named channel is not in the file; units cannot be converted.
/// The result has passed Validate().
RawHammerData ConvertUffToRawHammer(const UffFile& file, const std::string& source, const UffTimeOptions& options = {});

/// ReadUffFile followed by ConvertUffToRawHammer.
RawHammerData ReadUffRawHammer(const std::filesystem::path& path, const UffTimeOptions& options = {});

/// The records of the layout above for `data` (real double ordinates, SI units labels N and m/s^2,
/// m/s or m): outputs are numbered nodes 1..Nout with their direction codes, inputs 1001..1000+Nin;
/// record 4 carries the channel names. Throws InputError when a channel's direction is not +-x, +-y
/// or +-z.
std::vector<UffRecord> ConvertRawHammerToUff(const RawHammerData& data);

}  // namespace stagefit::measurement
