// csv.hpp: the one CSV reader is bounded while it reads (line bytes, columns, rows) and
// refuses what is not a regular file before reading, each by name.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <string>

#include "linksight/io/csv.hpp"
#include "linksight/io/error.hpp"
#include "test_support.hpp"

namespace linksight::io {
namespace {
namespace fs = std::filesystem;

std::string error_of(const fs::path& path, const CsvLimits& limits) {
  try {
    (void)read_csv(path, limits);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

CsvLimits rows(std::size_t n) {
  CsvLimits l;
  l.max_rows = n;
  return l;
}

TEST(Csv, SplitKeepsEmptyFields) {
  EXPECT_EQ(split("a,,b,", ','), (std::vector<std::string>{"a", "", "b", ""}));
  EXPECT_EQ(split("", ','), (std::vector<std::string>{}));
}

TEST(Csv, ReadsWithinItsLimits) {
  const fs::path dir = test::scratch_dir("Csv.ReadsWithinItsLimits");
  std::ofstream(dir / "t.csv") << "a,b\r\n1,2\n\n3,\n";
  const CsvTable t = read_csv(dir / "t.csv", rows(2));
  EXPECT_EQ(t.header, (std::vector<std::string>{"a", "b"}));
  ASSERT_EQ(t.rows.size(), 2u);
  EXPECT_EQ(t.rows[1], (std::vector<std::string>{"3", ""}));
  EXPECT_EQ(t.lines, (std::vector<int>{2, 4}));
}

TEST(Csv, EachLimitIsRefusedByNameWhileReading) {
  const fs::path dir = test::scratch_dir("Csv.EachLimitIsRefused");
  const std::string f = (dir / "t.csv").string();
  std::ofstream(f) << "a,b\n1,2\n3,4\n5,6\n";
  EXPECT_EQ(error_of(f, rows(2)), f + ":4: more than 2 rows (what this file can hold)");
  CsvLimits narrow = rows(10);
  narrow.max_columns = 1;
  EXPECT_EQ(error_of(f, narrow), f + ":1: 2 columns, more than 1 (this table has fewer)");
  CsvLimits shortline = rows(10);
  shortline.max_line_bytes = 3;
  EXPECT_EQ(error_of(f, shortline),
            f + ":1: a line of 3 bytes or more (a row of this table is short)");
  // The findings: a 200 MB line and a header of 10^8 columns were held whole before
  // anything was checked. Now the line stops at its limit (64 KiB), whatever follows.
  {
    std::ofstream big(dir / "line.csv");
    big << "a\n" << std::string(std::size_t{1} << 24, '9') << "\n";
  }
  EXPECT_EQ(error_of(dir / "line.csv", rows(10)),
            (dir / "line.csv").string() +
                ":2: a line of 65536 bytes or more (a row of this table is short)");
  {
    std::ofstream wide(dir / "wide.csv");
    for (int k = 0; k < 40000; ++k) wide << "c,";
    wide << "c\n";
  }
  EXPECT_NE(error_of(dir / "wide.csv", rows(10)).find(":1: a line of 65536 bytes or more"),
            std::string::npos);
  std::ofstream(dir / "cols.csv") << std::string(100, ',') << "\n";
  EXPECT_EQ(error_of(dir / "cols.csv", rows(10)),
            (dir / "cols.csv").string() + ":1: 101 columns, more than 64 (this table has fewer)");
}

TEST(Csv, WhatIsNotARegularFileIsRefusedBeforeReading) {
  const fs::path dir = test::scratch_dir("Csv.NotARegularFile");
  EXPECT_EQ(error_of(dir, rows(1)), dir.string() + ": a folder, not a CSV file");
  EXPECT_EQ(error_of("/dev/zero", rows(1)), "/dev/zero: not a regular file (a device or FIFO?)");
  // A FIFO with no writer would block an open() for ever.
  ASSERT_EQ(::mkfifo((dir / "fifo.csv").c_str(), 0600), 0);
  EXPECT_EQ(error_of(dir / "fifo.csv", rows(1)),
            (dir / "fifo.csv").string() + ": not a regular file (a device or FIFO?)");
  EXPECT_EQ(error_of(dir / "none.csv", rows(1)),
            (dir / "none.csv").string() + ": cannot be read (no such file)");
  std::ofstream(dir / "empty.csv");
  EXPECT_EQ(error_of(dir / "empty.csv", rows(1)), (dir / "empty.csv").string() + ": empty file");
}

}  // namespace
}  // namespace linksight::io
