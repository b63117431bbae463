// Tests of the camera-path CSV reader and writer: round trip bit for bit, and every kind of
// junk line rejected with the file name, the line number and what is wrong.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "terralod/pm/camera_path.hpp"

namespace pm = terralod::pm;

namespace {

std::string error_of(const std::string& text) {
  try {
    pm::parse_camera_path(text, "path.csv");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(CameraPath, ParsesRowsWithCommentsBlankLinesAndCrLf) {
  const auto p = pm::parse_camera_path(
      "# a scripted flight\r\n x , "
      "y,z,yaw,pitch,fovy\r\n\r\n1,2,3,45,-15,60\r\n-1.5e3,+2,3.25,-370,90,179.5\n",
      "p.csv", {.width_px = 640, .height_px = 480, .near_m = 0.5, .far_m = 1e4});
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].x, 1.0);
  EXPECT_EQ(p[0].yaw_deg, 45.0);
  EXPECT_EQ(p[0].pitch_deg, -15.0);
  EXPECT_EQ(p[1].x, -1500.0);
  EXPECT_EQ(p[1].y, 2.0);
  EXPECT_EQ(p[1].yaw_deg, -370.0);  // any finite yaw: it is an angle
  EXPECT_EQ(p[1].fovy_deg, 179.5);
  EXPECT_EQ(p[1].width_px, 640);
  EXPECT_EQ(p[1].near_m, 0.5);
  EXPECT_EQ(p[1].far_m, 1e4);
}

TEST(CameraPath, AByteOrderMarkAtTheStartIsIgnored) {
  // Excel's "CSV UTF-8" starts the file with EF BB BF; the header was refused as '???x'.
  const pm::CameraPathOptions o{.width_px = 640, .height_px = 480, .near_m = 0.5, .far_m = 1e4};
  const auto p = pm::parse_camera_path("\xEF\xBB\xBFx,y,z,yaw,pitch,fovy\r\n1,2,3,45,-15,60\r\n", "p.csv", o);
  ASSERT_EQ(p.size(), 1u);
  EXPECT_EQ(p[0].z, 3.0);
  // Only at the start: anywhere else it is junk.
  EXPECT_THROW(pm::parse_camera_path("x,y,z,yaw,pitch,fovy\n\xEF\xBB\xBF"
                                     "1,2,3,45,-15,60\n",
                                     "p.csv", o),
               std::runtime_error);
}

TEST(CameraPath, WriteThenReadIsBitExact) {
  std::vector<pm::Camera> path;
  for (int k = 0; k < 50; ++k) {
    pm::Camera c;
    c.x = 500000.0 + k * 0.1 + 1e-7, c.y = 5e6 / 3.0 + k, c.z = std::sqrt(2.0) * k;
    c.yaw_deg = k * 7.3, c.pitch_deg = -90.0 + k, c.fovy_deg = 60.0 + 1.0 / 3.0;
    path.push_back(c);
  }
  const std::string file = std::string(TERRALOD_TEST_TMP) + "/camera_path_roundtrip.csv";
  pm::write_camera_path(path, file);
  const auto back = pm::read_camera_path(file);
  ASSERT_EQ(back.size(), path.size());
  for (std::size_t k = 0; k < path.size(); ++k) {
    EXPECT_EQ(back[k].x, path[k].x);
    EXPECT_EQ(back[k].y, path[k].y);
    EXPECT_EQ(back[k].z, path[k].z);
    EXPECT_EQ(back[k].yaw_deg, path[k].yaw_deg);
    EXPECT_EQ(back[k].pitch_deg, path[k].pitch_deg);
    EXPECT_EQ(back[k].fovy_deg, path[k].fovy_deg);
  }
  EXPECT_FALSE(std::filesystem::exists(file + ".tmp"));
}

TEST(CameraPath, JunkIsAClearErrorNamingTheFileAndLine) {
  const std::string h = "x,y,z,yaw,pitch,fovy\n";
  EXPECT_EQ(error_of(""), "path.csv: line 0: no header line 'x,y,z,yaw,pitch,fovy' (empty file?)");
  EXPECT_EQ(error_of(h), "path.csv: line 1: no camera rows after the header");
  EXPECT_EQ(error_of("x,y,z,yaw,pitch\n1,2,3,4,5\n"),
            "path.csv: line 1: expected the header 'x,y,z,yaw,pitch,fovy', found 'x,y,z,yaw,pitch'");
  EXPECT_EQ(error_of(h + "1,2,3,4,5,60\n1,2,3\n"),
            "path.csv: line 3: expected 6 comma-separated numbers, found 3 fields");
  EXPECT_EQ(error_of(h + "1,2,abc,4,5,60\n"), "path.csv: line 2: z is not a finite number: 'abc'");
  EXPECT_EQ(error_of(h + "1,2,3,4,5,\n"), "path.csv: line 2: fovy is not a finite number: ''");
  EXPECT_EQ(error_of(h + "nan,2,3,4,5,60\n"), "path.csv: line 2: x is not a finite number: 'nan'");
  EXPECT_EQ(error_of(h + "1,inf,3,4,5,60\n"), "path.csv: line 2: y is not a finite number: 'inf'");
  EXPECT_EQ(error_of(h + "1,1e999,3,4,5,60\n"), "path.csv: line 2: y is not a finite number: '1e999'");
  EXPECT_EQ(error_of(h + "1,2,3,4,5 6,60\n"), "path.csv: line 2: pitch is not a finite number: '5 6'");
  EXPECT_EQ(error_of(h + "1,2,3,4,-91,60\n"), "path.csv: line 2: pitch must be in [-90, 90] degrees");
  EXPECT_EQ(error_of(h + "1,2,3,4,5,180\n"), "path.csv: line 2: fovy must be in (0, 180) degrees");
  EXPECT_EQ(error_of(h + "1,2,3,4,5,0\n"), "path.csv: line 2: fovy must be in (0, 180) degrees");
  std::string binary = h;  // (appending, not h + "...": GCC 12 warns wrongly on that one)
  binary.append("1,2,\x01\xff,4,5,60\n");
  EXPECT_EQ(error_of(binary),
            "path.csv: line 2: z is not a finite number: '?"
            "?'");
  pm::CameraPathOptions few;
  few.max_rows = 2;
  EXPECT_THROW(pm::parse_camera_path(h + "1,2,3,4,5,60\n1,2,3,4,5,60\n1,2,3,4,5,60\n", "p", few),
               std::runtime_error);
}

TEST(CameraPath, MissingAndNonRegularFilesNameThePath) {
  const std::string missing = std::string(TERRALOD_TEST_TMP) + "/no_such_path.csv";
  try {
    pm::read_camera_path(missing);
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), missing + ": no such file");
  }
  try {
    pm::read_camera_path(TERRALOD_TEST_TMP);
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), std::string(TERRALOD_TEST_TMP) + ": not a regular file");
  }
}
