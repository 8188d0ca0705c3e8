// UTC timestamps as text and as seconds. Times are counted in seconds since
// 1970-01-01T00:00:00 UTC on the proleptic Gregorian calendar without leap
// seconds (the POSIX time scale, as the orbit and product files that state
// UTC use it). Sub-second precision: doubles near 1.8e9 s keep ~0.2 us.
#pragma once

#include <cstdint>
#include <string>

namespace gissar {

// Days since 1970-01-01 of a proleptic Gregorian date.
int64_t DaysFromCivil(int64_t year, unsigned month, unsigned day);

// Seconds since the Unix epoch of a UTC timestamp
// "YYYY-MM-DD[T| ]hh:mm:ss[.fff…][Z]", with an optional "UTC=" prefix (as in
// ESA Earth Explorer files). Throws InputError naming `where` when the text
// is not such a timestamp or a field is out of range.
double ParseUtcSeconds(const std::string& text, const std::string& where);

// "YYYY-MM-DDThh:mm:ss.ffffffZ" of seconds since the Unix epoch (microsecond
// digits, rounded).
std::string FormatUtc(double unix_seconds);

}  // namespace gissar
