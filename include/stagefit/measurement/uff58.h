#pragma once
// Universal File Format dataset 58 ("function at nodal DOF") and its binary variant 58b, as written by
// modal-test systems. One dataset holds one function (time response, FRF, PSD, coherence, ...)
// between a response DOF and a reference DOF.
//
// Layout of one dataset (Fortran formats of the published record layout):
//   "    -1"                              delimiter
//   "    58" or "    58b" + 58b fields     58b: byte ordering (1 little, 2 big endian), floating-point
//                                          format (2 = IEEE 754), number of ASCII header lines (11),
//                                          number of bytes of binary data, then four zeros
//   Records 1-5  (A80)                     id lines (description, date, ...)
//   Record 6     (2(I5,I10),2(1X,A10,I10,I4))  function type, function id, version, load case,
//                                          response entity, node, direction, reference entity, node,
//                                          direction
//   Record 7     (3I10,3E13.5)             ordinate data type (2 real single, 4 real double, 5 complex
//                                          single, 6 complex double), number of points, abscissa
//                                          spacing (1 even, 0 uneven), abscissa minimum, increment,
//                                          z-axis value
//   Records 8-11 (I10,3I5,2(1X,A20))       abscissa, ordinate (numerator), ordinate denominator and
//                                          z-axis: specific data type, length/force/temperature unit
//                                          exponents, axis label, units label
//   Record 12    data                      ASCII: 6E13.5 (single), 4E20.12 (double), uneven real
//                                          double 2(E13.5,E20.12), uneven complex double E13.5,2E20.12;
//                                          binary: the same values as raw 4- or 8-byte IEEE reals
//   "    -1"                              delimiter
// With uneven spacing each point carries its abscissa (x, y) or (x, re, im); single-precision
// binary data stores the abscissa in single precision too.
//
// Units (ConvertUffToFrfData): FRF values are converted to SI from the units labels of records 9 and
// 10 (g = 9.80665 m/s^2, mm/s^2, in/s^2, ft/s^2, mm/s, in/s, mm, um, in; lbf, kN, N), or, when the
// labels name no unit, from the unit exponents of records 9-10 and the factors of dataset 164 (file
// value / factor = SI value). Node coordinates come from datasets 15 and 2411, in the units of
// dataset 164 (UffFile, ReadUffFile).

#include <Eigen/Core>

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stagefit/measurement/frf_data.h"

namespace stagefit::measurement {

/// Function types of record 6 that stagefit names; any other integer is kept as read.
namespace uff_function {
inline constexpr int kGeneral = 0;
inline constexpr int kTimeResponse = 1;
inline constexpr int kAutoSpectrum = 2;
inline constexpr int kCrossSpectrum = 3;
inline constexpr int kFrequencyResponseFunction = 4;
inline constexpr int kTransmissibility = 5;
inline constexpr int kCoherence = 6;
inline constexpr int kPowerSpectralDensity = 9;
}  // namespace uff_function

/// Specific data types of records 8-11 used to recognise an FRF's quantity.
namespace uff_data_type {
inline constexpr int kUnknown = 0;
inline constexpr int kGeneral = 1;
inline constexpr int kDisplacement = 8;
inline constexpr int kVelocity = 11;
inline constexpr int kAcceleration = 12;
inline constexpr int kExcitationForce = 13;
inline constexpr int kFrequency = 18;
inline constexpr int kTime = 17;
}  // namespace uff_data_type

/// Ordinate data type of record 7: precision and whether the ordinate is complex.
enum class UffOrdinateType : int {
  kRealSingle = 2,
  kRealDouble = 4,
  kComplexSingle = 5,
  kComplexDouble = 6,
};

/// One of the axis records 8-11.
struct UffAxis {
  int specific_data_type = uff_data_type::kUnknown;
  int length_unit_exponent = 0;
  int force_unit_exponent = 0;
  int temperature_unit_exponent = 0;
  std::string label = "NONE";        ///< at most 20 characters are written
  std::string units_label = "NONE";  ///< at most 20 characters are written
};

/// One dataset 58. Text fields read from a file are UTF-8: bytes that are not valid UTF-8 are read
/// as Latin-1 (the usual encoding of the "²" in old writers) and converted.
struct UffRecord {
  std::array<std::string, 5> id = {"NONE", "NONE", "NONE", "NONE", "NONE"};  ///< records 1-5
  int function_type = uff_function::kGeneral;
  int function_id = 0;
  int version_number = 0;
  int load_case_id = 0;
  std::string response_entity = "NONE";  ///< at most 10 characters are written
  int response_node = 0;
  int response_direction = 0;  ///< 0 scalar, +-1..3 translation X..Z, +-4..6 rotation X..Z
  std::string reference_entity = "NONE";
  int reference_node = 0;
  int reference_direction = 0;
  UffOrdinateType ordinate_type = UffOrdinateType::kComplexDouble;
  bool even_abscissa = true;        ///< record 7 abscissa spacing: true = 1 (even), false = 0
  double abscissa_minimum = 0.0;    ///< record 7; with even spacing x_i = minimum + i * increment
  double abscissa_increment = 0.0;  ///< record 7
  double z_axis_value = 0.0;
  UffAxis abscissa, ordinate, ordinate_denominator, z_axis;  ///< records 8, 9, 10, 11
  Eigen::VectorXd x;        ///< N abscissa values (s, Hz, ...), computed when the spacing is even
  Eigen::VectorXd real_y;   ///< N ordinate values when the ordinate type is real, else empty
  Eigen::VectorXcd complex_y;  ///< N ordinate values when the ordinate type is complex, else empty

  bool is_complex() const {
    return ordinate_type == UffOrdinateType::kComplexSingle ||
           ordinate_type == UffOrdinateType::kComplexDouble;
  }
  bool is_double() const {
    return ordinate_type == UffOrdinateType::kRealDouble ||
           ordinate_type == UffOrdinateType::kComplexDouble;
  }
  int num_points() const { return static_cast<int>(x.size()); }
};

/// How WriteUff58 encodes the data record.
enum class UffEncoding {
  kAscii,                ///< dataset 58, the Fortran formats above
  kBinaryLittleEndian,   ///< dataset 58b, byte ordering 1
  kBinaryBigEndian,      ///< dataset 58b, byte ordering 2
};

/// Reads every dataset 58/58b of a UFF file, in file order; datasets of other types (geometry 15,
/// 2411, units 164, ...) are skipped. Accepts CR LF line ends, header lines shorter than 80
/// columns, numbers that fill their fixed-width field or are separated by blanks, and a last data
/// line that is not full.
/// Throws InputError naming the file, the line (and column range) and what was expected for: a file
/// that cannot be read, no dataset 58 in it, a header field that is not a number, an unknown
/// ordinate data type, a count of points that does not match the data (a truncated file is reported,
/// never read past), a 58b byte count that disagrees with the number of points or exceeds the file,
/// a missing "-1" delimiter, and non-finite values.
std::vector<UffRecord> ReadUff58(const std::filesystem::path& path);

/// Same as ReadUff58 on the content of a file already in memory; `source` names it in messages.
std::vector<UffRecord> ParseUff58(std::string_view content, const std::string& source);

/// Formats datasets as UFF text (58) or 58b. Each record must have x and, according to its
/// ordinate_type, real_y or complex_y of the same length N >= 1; with even_abscissa the x values are
/// not written (the reader recomputes them from abscissa_minimum and abscissa_increment).
/// ASCII writes the standard formats: single precision E13.5 (6 significant digits), double
/// precision E20.12 (13 significant digits); binary writes the exact IEEE values. Record 7 prints
/// the abscissa minimum and increment as E13.5, like every writer of the format.
/// Throws InputError when a record is inconsistent (sizes, non-finite values).
std::string FormatUff58(const std::vector<UffRecord>& records, UffEncoding encoding);

/// Writes FormatUff58(records, encoding) to `path` atomically. Throws InputError as FormatUff58
/// and when the file cannot be written.
void WriteUff58(const std::filesystem::path& path, const std::vector<UffRecord>& records,
                UffEncoding encoding);

/// What a universal file holds besides its datasets 58: the node coordinates of datasets 15 and 2411
/// (converted to m with dataset 164's length factor) and the unit factors of dataset 164.
struct UffFile {
  std::vector<UffRecord> records;                ///< datasets 58 / 58b in file order
  std::map<int, Eigen::Vector3d> nodes_m;         ///< node label -> coordinates, m
  /// Dataset 164: file units per SI unit (value_file / factor = value_SI); 1 when absent.
  double length_factor = 1.0;
  double force_factor = 1.0;
  bool has_units = false;                          ///< a dataset 164 was read
  std::string units_description;                   ///< dataset 164 record 1, e.g. "SI: Meter (newton)"
};

/// Parses every dataset 58/58b, 15, 2411 and 164 of a universal file (others are skipped). Throws
/// InputError as ParseUff58 does, and for a node or units record that is not numbers (naming the
/// dataset, the line and the field).
UffFile ParseUffFile(std::string_view content, const std::string& source);
UffFile ReadUffFile(const std::filesystem::path& path);

/// The factor that converts a UFF FRF record's values to SI (header: from its units labels, else from
/// its unit exponents and the file's dataset 164 factors); 1 when nothing says otherwise. `how`
/// receives a short description ("g/N: x 9.80665") when not null.
double UffFrfScaleToSi(const UffRecord& record, const UffFile& file, std::string* how = nullptr);

/// A motion units label ("g", "m/s^2", "mm/s2", "in/s", "um", ...; blanks, parentheses and case
/// ignored): the quantity it measures and the SI value of one unit; nullopt when it names none of them.
std::optional<std::pair<FrfQuantity, double>> UffMotionUnitToSi(const std::string& label);
/// A force units label ("N", "kN", "lbf"): newtons per unit; nullopt otherwise.
std::optional<double> UffForceUnitToNewtons(const std::string& label);

/// Where a UFF node sits (UFF 58 carries node numbers only; positions come from elsewhere).
struct UffNodeLocation {
  std::string body;                                      ///< body carrying the node
  Eigen::Vector3d position_W = Eigen::Vector3d::Zero();  ///< m, in W at rest
};

/// Options of ConvertUffToFrfData.
struct UffFrfOptions {
  /// The FRFs' quantity; when absent it is recognised from the ordinate's specific data type
  /// (8 displacement, 11 velocity, 12 acceleration) or else from its units label ("m/s^2",
  /// "m/s2", "m/s²", "g" -> accelerance; "m/s" -> mobility; "m/N", "m" -> receptance).
  std::optional<FrfQuantity> quantity;
  /// Node number -> location; channels on listed nodes get geometry, the others have none.
  std::map<int, UffNodeLocation> nodes;
  /// Nodes of datasets 15 / 2411 (ReadUffMeasurement fills it from the file); a node listed here but not
  /// in `nodes` puts its channels on `node_body`. Empty `node_body`: such nodes give no geometry.
  std::map<int, Eigen::Vector3d> file_nodes_m;
  std::string node_body;
  /// Factors to SI per FRF record (UffFrfScaleToSi); empty = 1 for every record.
  std::vector<double> scale_to_si;
  /// Drops a first point at exactly 0 Hz (the DC line of an analyser's FFT, where an FRF of a
  /// hammer test carries no information and the frequency would fail Validate()).
  bool drop_zero_frequency = true;
};

/// Builds FrfData from the FRF records (function type 4) of a file; coherence records (type 6) for
/// the same response/reference pairs become the coherence, other function types are ignored.
/// Outputs are the distinct (response node, direction) pairs, inputs the distinct (reference node,
/// direction) pairs, both in order of first appearance; channels are named "<node>+X", "<node>-Z",
/// ... Direction codes +-1..3 give the unit vectors +-x, +-y, +-z of W; the position is unknown
/// unless `options.nodes` gives it. The FRF matrix must be complete and every record must share
/// the first record's abscissa (Hz) exactly. The result is validated (Validate()).
/// Throws InputError (naming `source`, the record and the problem) for: no FRF record, a real-valued
/// FRF record, rotational or scalar direction codes, differing abscissae, a missing or repeated
/// (response, reference) pair, a quantity that cannot be recognised, and every Validate() failure.
FrfData ConvertUffToFrfData(const std::vector<UffRecord>& records, const std::string& source,
                            const UffFrfOptions& options = {});

/// One complex-double FRF record (function type 4) per (output, input) pair, output-major, plus one
/// real-double coherence record (type 6) per pair when the data has coherence. Channel direction
/// codes are recovered from direction_W when it is +-x, +-y or +-z (else 0), node numbers from
/// channel names of the form "<node><sign><axis>" (else outputs are numbered 1..Nout and inputs
/// 1001..1000+Nin). The abscissa is even when every frequency equals f_0 + i*df exactly as the
/// reader recomputes it from the printed E13.5 values, otherwise uneven (x written per point).
std::vector<UffRecord> ConvertFrfDataToUff(const FrfData& data);

/// ReadUff58 followed by ConvertUffToFrfData.
FrfData ReadUffMeasurement(const std::filesystem::path& path, const UffFrfOptions& options = {});

/// ConvertFrfDataToUff followed by WriteUff58 (atomic). Binary encodings round-trip every double
/// exactly; ASCII keeps 13 significant digits of the FRF and coherence, and 6 of uneven frequencies.
void WriteUffMeasurement(const std::filesystem::path& path, const FrfData& data,
                         UffEncoding encoding = UffEncoding::kBinaryLittleEndian);

}  // namespace stagefit::measurement
