#include "specula/store/io/csv.h"

#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"
#include "specula/core/text.h"
#include "specula/core/wavelengths.h"

namespace specula::store {
namespace {

std::string shown40(std::string_view s) { return printable(s, 40); }

struct Cell {
  std::string text;
  std::size_t column = 0;  // 1-based field number
};

struct Row {
  std::size_t line = 0;
  std::vector<Cell> cells;
};

std::string format(double v) {
  std::array<char, 32> buf{};
  const auto [ptr, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  if (ec != std::errc{}) throw LibraryError("cannot format " + std::to_string(v));
  return {buf.data(), ptr};
}

std::string format(float v) {
  std::array<char, 32> buf{};
  const auto [ptr, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  if (ec != std::errc{}) throw LibraryError("cannot format " + std::to_string(v));
  return {buf.data(), ptr};
}

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(std::size_t line, std::size_t column, const std::string& problem) const {
    throw InputError(file_ + ":" + std::to_string(line) + (column ? ":" + std::to_string(column) : "") + ": " +
                     problem);
  }

  std::vector<Cell> split(std::string_view line, char delim, std::size_t line_no) const {
    std::vector<Cell> cells;
    std::size_t i = 0;
    for (;;) {
      Cell cell;
      cell.column = cells.size() + 1;
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t') && line[i] != delim) ++i;
      if (i < line.size() && line[i] == '"') {
        ++i;
        for (;;) {
          if (i >= line.size())
            fail(line_no, cell.column, "the quote is never closed; a quoted cell must end on its own line");
          if (line[i] == '"') {
            if (i + 1 < line.size() && line[i + 1] == '"') {
              cell.text += '"';
              i += 2;
              continue;
            }
            ++i;
            break;
          }
          cell.text += line[i++];
        }
        while (i < line.size() && line[i] != delim) {
          if (line[i] != ' ' && line[i] != '\t')
            fail(line_no, cell.column, "text after the closing quote; quote the whole cell");
          ++i;
        }
      } else {
        const std::size_t end = std::min(line.find(delim, i), line.size());
        cell.text = std::string(trim(line.substr(i, end - i)));
        i = end;
      }
      cells.push_back(std::move(cell));
      if (i >= line.size()) break;
      ++i;
    }
    return cells;
  }

  std::vector<Row> rows(std::string_view text) const {
    if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
    std::vector<Row> rows;
    char delim = 0;
    std::size_t line_no = 0, start = 0;
    while (start < text.size()) {
      std::size_t end = text.find_first_of("\r\n", start);
      if (end == std::string_view::npos) end = text.size();
      const std::string_view line = text.substr(start, end - start);
      ++line_no;
      start = end + (end < text.size() && text[end] == '\r' && end + 1 < text.size() && text[end + 1] == '\n' ? 2 : 1);
      const auto content = trim(line);
      if (content.empty() || content.front() == '#') continue;
      if (!delim) {
        if (line.find(',') != std::string_view::npos)
          delim = ',';
        else if (line.find('\t') != std::string_view::npos)
          delim = '\t';
        else if (line.find(';') != std::string_view::npos)
          delim = ';';
        else
          delim = ',';
      }
      rows.push_back(Row{line_no, split(line, delim, line_no)});
    }
    return rows;
  }

  static bool is_number(const std::string& s) {
    double v = 0;
    return parse(s, v);
  }

  template <typename T>
  static bool parse(std::string_view s, T& out) {
    if (s.starts_with('+')) {
      s.remove_prefix(1);
      if (s.starts_with('+') || s.starts_with('-')) return false;
    }
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
    return !s.empty() && ec == std::errc{} && ptr == s.data() + s.size();
  }

  template <typename T>
  T number(const Cell& c, std::size_t line, const char* what) const {
    if (c.text.empty()) fail(line, c.column, std::string("empty cell; every ") + what + " needs a value");
    T v{};
    std::string_view s = c.text;
    if (s.starts_with('+')) s.remove_prefix(1);
    const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec == std::errc::result_out_of_range && ptr == s.data() + s.size())
      fail(line, c.column, "'" + shown40(c.text) + "' is out of range for float32; rescale the data");
    if (!parse(c.text, v)) fail(line, c.column, "'" + shown40(c.text) + "' is not a number; fix the cell");
    if (!std::isfinite(v))
      fail(line, c.column, "'" + shown40(c.text) + "' is not a finite number; fill the gap or drop the spectrum");
    return v;
  }

  void check_count(const Row& r, std::size_t expected, const std::string& origin) const {
    if (r.cells.size() != expected)
      fail(r.line, std::min(r.cells.size(), expected) + 1,
           "row has " + std::to_string(r.cells.size()) + " cells but " + origin + " has " + std::to_string(expected) +
               "; every row needs the same number of cells");
  }

  // The bands in ascending order of their wavelengths wl (a list given unsorted is kept, its values permuted);
  // fails at the cell of a wavelength that is not positive or appears twice.
  std::vector<std::size_t> band_order(const std::vector<double>& wl, const std::vector<std::size_t>& lines,
                                      const std::vector<std::size_t>& columns, const std::string& hint) const {
    for (std::size_t i = 0; i < wl.size(); ++i)
      if (wl[i] <= 0) fail(lines[i], columns[i], "wavelength " + format(wl[i]) + " is not positive; " + hint);
    return ascending_band_order(wl, [&](std::size_t first, std::size_t second) {
      fail(lines[second], columns[second],
           "wavelength " + format(wl[second]) + " appears twice (also at line " + std::to_string(lines[first]) +
               ", column " + std::to_string(columns[first]) + "); remove one of them");
    });
  }

 private:
  std::string file_;
};

std::string read_all(const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw InputError(path.string() + ": cannot open: " + std::strerror(errno));
  std::string text;
  std::array<char, 65536> buf{};
  std::size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), f)) > 0) text.append(buf.data(), n);
  const bool failed = std::ferror(f) != 0;
  const int err = errno;
  if (std::fclose(f) != 0 || failed)
    throw LibraryError(path.string() + ": read failed: " + std::strerror(failed ? err : errno));
  return text;
}

bool looks_like_wavelength_label(std::string_view s) {
  std::string l(trim(s));
  for (char& c : l)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return l.find("wavelength") != std::string::npos || l == "nm" || l == "lambda" || l == "wl" ||
         l.starts_with("lambda") || l.starts_with("nm ") || l.starts_with("nm(") || l == "wavelength_nm";
}

std::string quoted(const std::string& name) {
  const bool needs =
      name.empty() || name.find_first_of(",\";\t#") != std::string::npos || name.front() == ' ' || name.back() == ' ';
  if (!needs) return name;
  std::string out = "\"";
  for (char c : name) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

// A file whose first column lists wavelengths and whose header row names the spectra (one column each).
void read_transposed(const Reader& rd, const std::vector<Row>& rows, const std::string& file, Collection& col) {
  const Row& head = rows.front();
  const auto& hc = head.cells;
  const std::size_t n = hc.size() - 1;
  for (std::size_t i = 1; i < hc.size(); ++i) {
    if (hc[i].text.empty()) rd.fail(head.line, hc[i].column, "empty spectrum name in the header; name every column");
    col.names.push_back(hc[i].text);
  }
  if (rows.size() < 2) rd.fail(head.line, 0, "header but no wavelength rows");
  std::vector<double> wl;
  std::vector<std::size_t> lines, columns;
  std::vector<float> by_row;
  by_row.reserve((rows.size() - 1) * n);
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const Row& row = rows[r];
    rd.check_count(row, hc.size(), "the header on line " + std::to_string(head.line));
    wl.push_back(rd.number<double>(row.cells[0], row.line, "wavelength row"));
    lines.push_back(row.line);
    columns.push_back(1);
    for (std::size_t i = 1; i < row.cells.size(); ++i)
      by_row.push_back(rd.number<float>(row.cells[i], row.line, "spectrum"));
  }
  const std::vector<std::size_t> order =
      rd.band_order(wl, lines, columns, "the first column must list wavelengths in nm");
  const std::size_t B = wl.size();
  col.values.resize(n * B);
  std::vector<double> nm(B);
  for (std::size_t b = 0; b < B; ++b) {
    nm[b] = wl[order[b]];
    for (std::size_t s = 0; s < n; ++s) col.values[s * B + b] = by_row[order[b] * n + s];
  }
  col.wavelengths = WavelengthGrid(std::move(nm), file);
}

// Where the spectra of a row-per-spectrum file lie: the first data row, the name column (0 or 1), the bands and the
// file column of each band by ascending wavelength; col.wavelengths is set from the header row or `wavelengths`.
struct RowLayout {
  bool has_header = true;
  std::size_t first_data = 0, name_col = 0, B = 0;
  std::vector<std::size_t> order;
};

RowLayout row_layout(const Reader& rd, const Row& head, const WavelengthGrid& wavelengths, const std::string& file,
                     Collection& col) {
  const auto& hc = head.cells;
  // Row layout: is the first row a wavelength header?
  const bool head_named = !Reader::is_number(hc[0].text);
  std::vector<double> head_wl;
  bool head_all_numeric = true;
  for (std::size_t i = head_named ? 1 : 0; i < hc.size(); ++i) {
    double v = 0;
    if (!Reader::parse(hc[i].text, v) || !std::isfinite(v)) {
      head_all_numeric = false;
      break;
    }
    head_wl.push_back(v);
  }
  RowLayout l;
  bool& has_header = l.has_header;
  if (!wavelengths.empty()) {
    has_header = head_all_numeric && head_wl.size() == wavelengths.size();
    for (std::size_t i = 0; has_header && i < head_wl.size(); ++i)
      has_header = std::abs(head_wl[i] - wavelengths[i]) <= 1e-3;
  }

  std::size_t& first_data = l.first_data;
  std::size_t& name_col = l.name_col;
  std::size_t& B = l.B;
  std::vector<std::size_t>& order = l.order;  // file column of each band, by ascending wavelength
  if (has_header) {
    const std::string hint =
        "the first row must list wavelengths in nm (or give the `wavelengths` option for a file without a header row)";
    std::vector<std::size_t> lines, columns;
    std::vector<double> wl;
    for (std::size_t i = head_named ? 1 : 0; i < hc.size(); ++i) {
      double v = 0;
      if (!Reader::parse(hc[i].text, v) || !std::isfinite(v))
        rd.fail(head.line, hc[i].column, "header cell '" + shown40(hc[i].text) + "' is not a wavelength; " + hint);
      wl.push_back(v);
      lines.push_back(head.line);
      columns.push_back(hc[i].column);
    }
    if (wl.empty()) rd.fail(head.line, 0, "the header row has no wavelengths; " + hint);
    order = rd.band_order(wl, lines, columns, hint);
    if (wl[order.back()] < 100)
      rd.fail(head.line, 0,
              "header values " + format(wl[order.front()]) + " to " + format(wl[order.back()]) +
                  " are not wavelengths in nm; " + hint);
    B = wl.size();
    name_col = head_named ? 1 : 0;
    first_data = 1;
    std::vector<double> nm;
    for (const std::size_t b : order) nm.push_back(wl[b]);
    col.wavelengths = WavelengthGrid(std::move(nm), file);
  } else {
    B = wavelengths.size();
    bool header_like = head_all_numeric && head_wl.size() >= 2 && head_wl.front() >= 100;
    for (std::size_t i = 1; header_like && i < head_wl.size(); ++i) header_like = head_wl[i] > head_wl[i - 1];
    const bool fits_data = hc.size() == B + 1 || (hc.size() == B && !head_named);
    if (header_like && !fits_data)
      rd.fail(head.line, 0,
              "the header row lists " + std::to_string(head_wl.size()) + " wavelengths " + format(head_wl.front()) +
                  "-" + format(head_wl.back()) + " nm but the `wavelengths` option gives " + std::to_string(B) +
                  "; drop the `wavelengths` option to use the file's");
    if (hc.size() == B + 1)
      name_col = 1;
    else if (hc.size() != B)
      rd.fail(head.line, 0,
              "row has " + std::to_string(hc.size()) + " cells but the `wavelengths` option has " + std::to_string(B) +
                  " bands; give a name and one value per band, or add a header row of wavelengths");
    col.wavelengths = wavelengths;
    order.resize(B);
    std::iota(order.begin(), order.end(), std::size_t{0});
  }
  return l;
}

// The spectra rows of a row-per-spectrum file laid out as `l`.
void read_rows(const Reader& rd, const std::vector<Row>& rows, const RowLayout& l, Collection& col) {
  const Row& head = rows.front();
  const bool has_header = l.has_header;
  const std::size_t first_data = l.first_data, name_col = l.name_col, B = l.B;
  const std::vector<std::size_t>& order = l.order;
  const std::size_t expected = name_col + B;
  const std::string origin = has_header ? "the header on line " + std::to_string(head.line)
                                        : "the first row (line " + std::to_string(head.line) + ")";
  col.values.reserve((rows.size() - first_data) * B);
  std::vector<float> spectrum(B);  // one row in the file's column order
  for (std::size_t r = first_data; r < rows.size(); ++r) {
    const Row& row = rows[r];
    rd.check_count(row, expected, origin);
    if (name_col) {
      if (row.cells[0].text.empty()) rd.fail(row.line, 1, "empty spectrum name; name every row");
      col.names.push_back(row.cells[0].text);
    } else {
      col.names.push_back("spectrum_" + std::to_string(col.names.size() + 1));
    }
    for (std::size_t b = 0; b < B; ++b) spectrum[b] = rd.number<float>(row.cells[name_col + b], row.line, "spectrum");
    for (const std::size_t b : order) col.values.push_back(spectrum[b]);
  }
  if (col.names.empty()) rd.fail(head.line, 0, "a header row but no spectra; add one row per spectrum");
}

}  // namespace

Collection read_csv_collection(const std::filesystem::path& path, const WavelengthGrid& wavelengths) {
  const std::string file = path.string();
  const Reader rd(file);
  const std::vector<Row> rows = rd.rows(read_all(path));
  if (rows.empty()) throw InputError(file + ": no rows; the file is empty");

  Collection col;
  col.provenance.source_file = file;
  col.provenance.importer = "csv";
  const Row& head = rows.front();
  const auto& hc = head.cells;

  bool transposed = false;
  if (hc.size() >= 2 && !Reader::is_number(hc[0].text) && looks_like_wavelength_label(hc[0].text)) transposed = true;
  if (hc.size() >= 2) {
    bool any_numeric = false;
    for (std::size_t i = 1; i < hc.size(); ++i) any_numeric = any_numeric || Reader::is_number(hc[i].text);
    transposed = transposed || !any_numeric;
  }

  if (transposed) {
    read_transposed(rd, rows, file, col);
    return col;
  }
  read_rows(rd, rows, row_layout(rd, head, wavelengths, file, col), col);
  return col;
}

void write_csv_collection(const std::filesystem::path& path, const Collection& collection) {
  const std::size_t B = collection.bands(), N = collection.size();
  if (B == 0) throw UsageError("write_csv_collection: the collection has no wavelengths");
  if (collection.values.size() != N * B)
    throw UsageError("write_csv_collection: " + std::to_string(collection.values.size()) + " values for " +
                     std::to_string(N) + " spectra x " + std::to_string(B) + " bands");
  std::string out = "name";
  for (double w : collection.wavelengths.values()) out += "," + format(w);
  out += '\n';
  for (std::size_t s = 0; s < N; ++s) {
    const std::string& name = collection.names[s];
    if (name.find_first_of("\r\n") != std::string::npos)
      throw UsageError("write_csv_collection: spectrum name '" + shown40(name) + "' contains a line break");
    out += quoted(name);
    for (std::size_t b = 0; b < B; ++b) {
      const float v = collection.values[s * B + b];
      if (!std::isfinite(v))
        throw UsageError("write_csv_collection: spectrum '" + shown40(name) + "' is not finite at " +
                         format(collection.wavelengths[b]) + " nm; CSV cannot hold it");
      out += "," + format(v);
    }
    out += '\n';
  }

  AtomicOutput tmp(path);
  std::FILE* f = std::fopen(tmp.temp_path().c_str(), "wb");
  if (!f)
    throw LibraryError(path.string() + ": cannot create " + tmp.temp_path().string() + ": " + std::strerror(errno));
  const bool ok = std::fwrite(out.data(), 1, out.size(), f) == out.size();
  const int err = errno;
  if (std::fclose(f) != 0 || !ok)
    throw LibraryError(path.string() + ": write failed: " + std::strerror(ok ? errno : err));
  tmp.commit();
}

}  // namespace specula::store
