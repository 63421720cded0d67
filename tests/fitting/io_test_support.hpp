// Helpers shared by the I/O test suites: scratch directories, file contents, hand-made binary
// data and sample clouds.
#pragma once

#include "stampscan/fitting/cloud.hpp"
#include "stampscan/fitting/ply_io.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <system_error>
#include <vector>

namespace stampscan::fitting::test {

// A fresh, uniquely named directory under the system temp directory, removed with its contents.
class TempDir {
 public:
  TempDir() {
    std::random_device device;
    path_ = std::filesystem::temp_directory_path() /
            ("stampscan_io_test_" + std::to_string(device()) + "_" + std::to_string(device()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(path_)) names.push_back(entry.path().filename().string());
    return names;
  }

 private:
  std::filesystem::path path_;
};

inline std::filesystem::path writeFile(const std::filesystem::path& file, const std::string& bytes) {
  std::ofstream out(file, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return file;
}

inline std::string readFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline ::testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "\"" << text << "\" does not contain \"" << part << "\"";
}

// Appends binary values in a chosen byte order, for hand-made binary PLY bodies.
class Bytes {
 public:
  explicit Bytes(bool bigEndian = false) : bigEndian_(bigEndian) {}
  template <class T>
  Bytes& put(T value) {
    auto raw = std::bit_cast<std::array<char, sizeof(T)>>(value);
    if (bigEndian_ != (std::endian::native == std::endian::big)) std::reverse(raw.begin(), raw.end());
    text_.append(raw.data(), raw.size());
    return *this;
  }
  const std::string& str() const { return text_; }

 private:
  bool bigEndian_;
  std::string text_;
};

// A cloud with every attribute: normals, strain, colours and two named scalars.
inline Cloud sampleCloud(std::size_t n) {
  Cloud cloud;
  std::mt19937 random(42);
  std::uniform_real_distribution<double> coordinate(-500.0, 500.0);
  for (std::size_t i = 0; i < n; ++i) {
    cloud.positions.emplace_back(coordinate(random), coordinate(random), coordinate(random) / 3.0);
    cloud.normals.push_back(Vec3(coordinate(random), coordinate(random), 1.0).normalized());
    cloud.strain.push_back(coordinate(random) * 1e-4);
    cloud.colors.push_back({static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(255 - i % 256), 7});
    cloud.scalars["major_strain"].push_back(coordinate(random) * 1e-3);
    cloud.scalars["minor_strain"].push_back(-0.1 * static_cast<double>(i));
  }
  return cloud;
}

// With float precision every value comes back as the nearest float.
inline double stored(double value, PlyPrecision precision) {
  return precision == PlyPrecision::Float ? static_cast<double>(static_cast<float>(value)) : value;
}

// Compares attribute by attribute; with float precision, against the values rounded to float.
inline void expectSameCloud(const Cloud& expected, const Cloud& actual, PlyPrecision precision) {
  ASSERT_EQ(actual.size(), expected.size());
  ASSERT_EQ(actual.normals.size(), expected.normals.size());
  ASSERT_EQ(actual.strain.size(), expected.strain.size());
  ASSERT_EQ(actual.colors.size(), expected.colors.size());
  ASSERT_EQ(actual.scalars.size(), expected.scalars.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(actual.positions[i][k], stored(expected.positions[i][k], precision)) << "point " << i;
      if (expected.hasNormals()) {
        ASSERT_EQ(actual.normals[i][k], stored(expected.normals[i][k], precision));
      }
    }
    if (expected.hasStrain()) {
      ASSERT_EQ(actual.strain[i], stored(expected.strain[i], precision));
    }
    if (expected.hasColors()) {
      ASSERT_EQ(actual.colors[i], expected.colors[i]);
    }
    for (const auto& [name, values] : expected.scalars) {
      ASSERT_TRUE(actual.scalars.count(name)) << name;
      ASSERT_EQ(actual.scalars.at(name)[i], stored(values[i], precision)) << name;
    }
  }
}

}  // namespace stampscan::fitting::test
