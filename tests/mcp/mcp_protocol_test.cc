// The Model Context Protocol's vocabulary without a socket (simgate/mcp/protocol.h): the
// revisions, the tools' names and definitions made from service descriptors, the deadline
// argument, a finished call as a tool result (images as image content), progress.
#include "simgate/mcp/protocol.h"

#include <gtest/gtest.h>

namespace simgate::mcp {
namespace {

ServiceDescriptor service(std::string component, std::string name, bool is_async = false) {
  ServiceDescriptor d;
  d.component = std::move(component);
  d.name = std::move(name);
  d.is_async = is_async;
  return d;
}

TEST(McpProtocol, TheRevisionIsTheClientsWhenServedElseTheNewest) {
  EXPECT_EQ(negotiate_version("2025-06-18"), "2025-06-18");
  EXPECT_EQ(negotiate_version("2025-11-25"), "2025-11-25");
  EXPECT_EQ(negotiate_version("2024-11-05"), "2025-11-25");
  EXPECT_EQ(negotiate_version(""), "2025-11-25");
  EXPECT_TRUE(is_served_version("2025-03-26"));
  EXPECT_FALSE(is_served_version("2026-01-01"));
}

TEST(McpProtocol, ToolNamesAreTheServicesWithUnderscoresForDots) {
  EXPECT_EQ(tool_name("simulation.list_robots"), "simulation_list_robots");
  EXPECT_EQ(tool_name("rover.camera.get_image"), "rover_camera_get_image");
  EXPECT_EQ(tool_name("w3/rover.camera.get_image"), "w3_rover_camera_get_image");
  std::vector<std::string> skipped;
  const auto tools =
      make_tools({service("rover.camera", "get_image"), service("simulation", "step")}, skipped);
  ASSERT_EQ(tools.size(), 2u);
  EXPECT_EQ(tools.at("rover_camera_get_image").service.qualified_name(), "rover.camera.get_image");
  EXPECT_TRUE(skipped.empty());
}

TEST(McpProtocol, ANameClashGivesTheSecondServiceHyphensAndAThirdNoTool) {
  std::vector<std::string> skipped;
  // taken in the order of their qualified names ('-' < '.' < '_'): r.a.b, r.a_b and r_a.b
  // would all be r_a_b; r.a_b's hyphen form is r-a.b's already
  const auto tools = make_tools(
      {service("r_a", "b"), service("r.a", "b"), service("r", "a_b"), service("r-a", "b")},
      skipped);
  ASSERT_EQ(tools.size(), 3u);
  EXPECT_EQ(tools.at("r-a_b").service.qualified_name(), "r-a.b");
  EXPECT_EQ(tools.at("r_a_b").service.qualified_name(), "r.a.b");
  EXPECT_EQ(tools.at("r_a-b").service.qualified_name(), "r_a.b");
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_EQ(skipped[0], "r.a_b");
}

TEST(McpProtocol, ADefinitionHasTheParametersSchemaAndForAsyncServicesADeadline) {
  ServiceDescriptor goto_ = service("robot.waypoint", "goto", true);
  goto_.doc = "Goes to a point";
  goto_.params = {{"x", json{{"type", "number"}}, "number", std::nullopt},
                  {"speed", json{{"type", "number"}}, "number", json(1.0)}};
  const json d = tool_definition(Tool{"robot_waypoint_goto", goto_});
  EXPECT_EQ(d["name"], "robot_waypoint_goto");
  EXPECT_EQ(d["title"], "robot.waypoint.goto");
  EXPECT_NE(d["description"].get<std::string>().find("Goes to a point"), std::string::npos);
  EXPECT_NE(d["description"].get<std::string>().find("progress"), std::string::npos);
  const json& schema = d["inputSchema"];
  EXPECT_EQ(schema["type"], "object");
  EXPECT_EQ(schema["required"], json::array({"x"}));
  EXPECT_EQ(schema["properties"]["speed"]["default"], 1.0);
  EXPECT_EQ(schema["properties"]["deadline_ms"]["type"], "integer");
  EXPECT_FALSE(schema.contains("description"));

  const json sync = tool_definition(Tool{"a_b", service("a", "b")});
  EXPECT_FALSE(sync["inputSchema"]["properties"].contains("deadline_ms"));
  EXPECT_EQ(sync["inputSchema"]["properties"], json::object());
}

TEST(McpProtocol, TheDeadlineIsTakenOutOfTheArgumentsAndChecked) {
  const Tool slow{"a_b", service("a", "b", true)};
  std::string why;
  json arguments = {{"x", 1}, {"deadline_ms", 250}};
  EXPECT_EQ(take_deadline(arguments, slow, why), std::chrono::milliseconds(250));
  EXPECT_EQ(why, "");
  EXPECT_EQ(arguments, (json{{"x", 1}}));
  json none = {{"x", 1}};
  EXPECT_EQ(take_deadline(none, slow, why), std::chrono::milliseconds(0));
  for (const json& bad : {json(0), json(-5), json(1.5), json("soon")}) {
    json a = {{"deadline_ms", bad}};
    take_deadline(a, slow, why);
    EXPECT_NE(why.find("deadline_ms must be an integer"), std::string::npos) << bad;
  }
  // a sync service's deadline_ms is its own argument (none is taken)
  const Tool quick{"a_c", service("a", "c")};
  json own = {{"deadline_ms", 5}};
  EXPECT_EQ(take_deadline(own, quick, why), std::chrono::milliseconds(0));
  EXPECT_TRUE(own.contains("deadline_ms"));
}

TEST(McpProtocol, ASuccessIsTextAndStructuredContent) {
  const json object = tool_result(Outcome::success(json{{"x", 1.5}, {"name", "r"}}));
  EXPECT_EQ(object["isError"], false);
  EXPECT_EQ(object["structuredContent"], (json{{"x", 1.5}, {"name", "r"}}));
  EXPECT_EQ(json::parse(object["content"][0]["text"].get<std::string>()),
            object["structuredContent"]);
  const json list = tool_result(Outcome::success(json::array({"robot"})));
  EXPECT_EQ(list["structuredContent"], (json{{"result", {"robot"}}}));
  const json none = tool_result(Outcome::success(std::nullopt));
  EXPECT_EQ(none["structuredContent"], (json{{"result", nullptr}}));
  EXPECT_EQ(none["content"][0]["text"], "null");
}

TEST(McpProtocol, TheResultsTextIsTheResultsJson) {
  const std::vector<Outcome> outcomes = {
      Outcome::success(json{{"x", 1.5}, {"name", "r\"q"}}),
      Outcome::success(json::array({"robot"})),
      Outcome::success(std::nullopt),
      Outcome::success(json(3)),
      Outcome::success(json{{"image", "iVBORw0K"}, {"format", "png"}}),
      Outcome::failed(Failure::service_error, "no")};
  for (const Outcome& outcome : outcomes) {
    Outcome a = outcome, b = outcome;
    EXPECT_EQ(json::parse(tool_result_text(std::move(a))), tool_result(std::move(b)));
  }
}

TEST(McpProtocol, PngImageRecordsBecomeImageContent) {
  const json record = {{"width", 2}, {"height", 1}, {"format", "png"}, {"image", "iVBORw0K"}};
  const json raw = {{"width", 2}, {"height", 1}, {"format", "raw"}};
  const json r = tool_result(Outcome::success(json{{"images", {record, raw, record}}}));
  ASSERT_EQ(r["content"].size(), 3u);
  EXPECT_EQ(r["content"][1],
            (json{{"type", "image"}, {"data", "iVBORw0K"}, {"mimeType", "image/png"}}));
  EXPECT_EQ(r["structuredContent"]["images"][0]["image"], "(image content 1)");
  EXPECT_EQ(r["structuredContent"]["images"][2]["image"], "(image content 2)");
  EXPECT_EQ(r["structuredContent"]["images"][1], raw);
  EXPECT_EQ(r["content"][0]["text"].get<std::string>().find("iVBORw0K"), std::string::npos);
}

TEST(McpProtocol, FailuresArePreemptionsAreToolErrorsWithTheReason) {
  const json failed = tool_result(Outcome::failed(Failure::bad_arguments, "x: expected a number"));
  EXPECT_EQ(failed["isError"], true);
  EXPECT_EQ(failed["content"][0]["text"], "x: expected a number");
  EXPECT_FALSE(failed.contains("structuredContent"));
  Outcome preempted;
  preempted.status = Status::preempted;
  preempted.message = "a newer goto";
  EXPECT_EQ(tool_result(std::move(preempted))["content"][0]["text"], "preempted: a newer goto");
}

TEST(McpProtocol, ProgressCountsReportsOrTheStepsDone) {
  const json steps =
      progress_notification("t1", 3, json{{"steps_done", 40}, {"steps_requested", 100}});
  EXPECT_EQ(steps["method"], "notifications/progress");
  EXPECT_EQ(steps["params"]["progressToken"], "t1");
  EXPECT_EQ(steps["params"]["progress"], 40);
  EXPECT_EQ(steps["params"]["total"], 100);
  const json other = progress_notification(7, 3, json{{"distance_left", 1.5}});
  EXPECT_EQ(other["params"]["progress"], 3);
  EXPECT_FALSE(other["params"].contains("total"));
  EXPECT_EQ(json::parse(other["params"]["message"].get<std::string>()),
            (json{{"distance_left", 1.5}}));
}

TEST(McpProtocol, InitializeSaysTheRevisionAndTools) {
  const json r = initialize_result("2025-06-18", "1.2.3");
  EXPECT_EQ(r["protocolVersion"], "2025-06-18");
  EXPECT_EQ(r["capabilities"]["tools"]["listChanged"], true);
  EXPECT_EQ(r["capabilities"]["resources"]["subscribe"], true);
  EXPECT_EQ(r["serverInfo"]["name"], "simgate");
  EXPECT_EQ(r["serverInfo"]["version"], "1.2.3");
}

}  // namespace
}  // namespace simgate::mcp
