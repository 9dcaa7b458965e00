/* The one reader of point lists (proto/sm_points_csv.h): warp's points
 * and --landmarks alike.  Plain CSV as before (header, CRLF, blanks,
 * bad fields named by line and field), '#' comments anywhere, a header
 * that names x, y, z among other columns (labels, ids, quoted fields
 * with commas) whose other columns come back in the output in their
 * places, a warp's own output read back (its inside column replaced),
 * Slicer's .fcsv and .mrk.json with their frames, and the limits. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "sm_points_csv.h"

static sm_points parse_ok(const char *text)
{
    sm_points p;
    sm_error err;
    sm_error_clear(&err);
    if (sm_points_csv_parse(text, strlen(text), 0, &p, &err) != SM_OK)
        fail_msg("'%s': %s", text, err.msg);
    return p;
}

static char *format(const sm_points *p)
{
    uint8_t *inside = calloc((size_t)p->n, 1);
    assert_non_null(inside);
    for (int64_t i = 0; i < p->n; i++)
        inside[i] = (uint8_t)(i % 2);
    size_t len;
    char *out = sm_points_csv_format(p, p->xyz, inside, 0, &len);
    assert_non_null(out);
    assert_int_equal(strlen(out), len);
    free(inside);
    return out;
}

static void test_plain(void **state)
{
    (void)state;
    sm_points p = parse_ok("# points\r\nx, y, z\r\n1, 2, 3\r\n\n 4.5 ,5e-1,-6\n# a comment\n7,8,9");
    assert_int_equal(p.n, 3);
    assert_int_equal(p.dim, 3);
    assert_true(p.xyz[0] == 1 && p.xyz[3] == 4.5 && p.xyz[4] == 0.5 && p.xyz[5] == -6 &&
                p.xyz[8] == 9);
    assert_int_equal(p.header_line, 1);
    assert_int_equal(p.frame, SM_POINTS_FRAME_UNSTATED);
    /* the line of each point, comments and blanks counted */
    const char *t = "# points\r\nx, y, z\r\n1, 2, 3\r\n\n 4.5 ,5e-1,-6\n# a comment\n7,8,9";
    assert_int_equal(sm_points_csv_line(t, strlen(t), 1, 0), 3);
    assert_int_equal(sm_points_csv_line(t, strlen(t), 1, 1), 5);
    assert_int_equal(sm_points_csv_line(t, strlen(t), 1, 2), 7);
    char *out = format(&p);
    assert_string_equal(out, "x, y, z,inside\n1,2,3,0\n4.5,0.5,-6,1\n7,8,9,0\n");
    free(out);
    sm_points_release(&p);
}

static void test_refused(void **state)
{
    (void)state;
    static const struct {
        const char *text, *message;
    } bad[] = {
        {"1,2\n1,2,3\n", "line 2: expected 2 coordinates, found 3"},
        {"1,2,3,4\n", "line 1: expected 2 or 3 coordinates, found 4"},
        {"1,2,3\n1,x,3\n", "line 2, field 2: 'x' is not a finite decimal number"},
        {"1,2,inf\n", "line 1, field 3: 'inf' is not a finite decimal number"},
        {"1,2,1e999\n", "line 1, field 3: '1e999' is not a finite decimal number"},
        {"1,,3\n", "line 1, field 2: '' is not"},
        {"x,y,z\n# only a header\n", "no point"},
        {"", "no point"},
        {"1,2,3\nx,y,z\n", "line 2, field 1: 'x' is not"},
        {"label,x,y,z\nF-1,1,2\n", "line 2: expected 4 fields as the header names, found 3"},
        {"label,x,y,z\nF-1,1,b,3\n", "line 2, field 3 (y): 'b' is not"},
        {"label,x,y\n\"F-1,1,2\n", "line 2: a quote is not closed"},
        {"{\"markups\": []}", "non-empty \"markups\""},
        {"{\"markups\": [{\"controlPoints\": [{\"position\": [1, 2]}]}]}",
         "markups[0].controlPoints[0].position is three finite numbers"},
        {"{\"markups\": [{\"coordinateSystem\": \"XYZ\"}]}", "coordinateSystem is LPS or RAS"},
        {"{\"markups\": [", "not JSON"},
        {"# Markups fiducial file version = 4.11\n# CoordinateSystem = 7\n", "CoordinateSystem"},
        {"# Markups fiducial file version = 4.11\n# columns = id,a,b\n1,2,3\n",
         "the .fcsv's columns name no x, y, z"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sm_points p;
        sm_error err;
        sm_error_clear(&err);
        assert_int_not_equal(sm_points_csv_parse(bad[i].text, strlen(bad[i].text), 0, &p, &err),
                             SM_OK);
        if (!strstr(err.msg, bad[i].message))
            fail_msg("case %zu: '%s' lacks '%s'", i, err.msg, bad[i].message);
        assert_null(p.xyz);
        assert_null(p.header);
        assert_null(p.lines);
    }
    /* one point past the limit: refused, naming the line */
    sm_points p;
    sm_error err;
    assert_int_equal(sm_points_csv_parse("1,2,3\n1,2,3\n1,2,3\n", 18, 2, &p, &err), SM_ERR_NOMEM);
    assert_non_null(strstr(err.msg, "line 3: more than 2 points"));
    const char nul[] = "1,2,3\n1,\0,3\n";
    assert_int_equal(sm_points_csv_parse(nul, sizeof nul - 1, 0, &p, &err), SM_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "line 2: NUL byte"));
    assert_int_equal(sm_points_read_file("/nonexistent/l.csv", 0, 0, &p, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "/nonexistent/l.csv: cannot open"));
}

/* A label column (what Slicer and landmark tools write), quoted fields
 * with a comma and a quote: the coordinates by name, the rest back in
 * its place; the output read again gives the same points and columns. */
static void test_named_columns(void **state)
{
    (void)state;
    sm_points p = parse_ok("# landmarks\nid,Z,label,X,Y\n1,3,\"tip, left\",1,2\n"
                           "2,6.5,\"say \"\"hi\"\"\",4,5\n");
    assert_int_equal(p.dim, 3);
    assert_int_equal(p.n, 2);
    double want[6] = {1, 2, 3, 4, 5, 6.5};
    assert_memory_equal(p.xyz, want, sizeof want);
    char *out = format(&p);
    assert_string_equal(out, "id,Z,label,X,Y,inside\n1,3,\"tip, left\",1,2,0\n"
                             "2,6.5,\"say \"\"hi\"\"\",4,5,1\n");
    /* a warp's output is an input: its inside column replaced */
    sm_points q = parse_ok(out);
    assert_memory_equal(q.xyz, want, sizeof want);
    assert_int_equal(q.inside_col, 5);
    char *again = format(&q);
    assert_string_equal(again, out);
    free(again);
    free(out);
    sm_points_release(&q);
    sm_points_release(&p);
    /* 2D, and a header of exactly x,y,inside */
    sm_points r = parse_ok("x,y,inside\n0.5,1,1\n2,3,0\n");
    assert_int_equal(r.dim, 2);
    out = format(&r);
    assert_string_equal(out, "x,y,inside\n0.5,1,0\n2,3,1\n");
    free(out);
    sm_points_release(&r);
}

static void test_slicer(void **state)
{
    (void)state;
    const char *fcsv = "# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n"
                       "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n"
                       "vtkMRMLMarkupsFiducialNode_0,1,2,3,0,0,0,1,1,1,0,F-1,,vtkMRMLModelNode4\n"
                       "vtkMRMLMarkupsFiducialNode_1,4,5,6.5,0,0,0,1,1,1,0,F-2,,\n";
    sm_points p = parse_ok(fcsv);
    double want[6] = {1, 2, 3, 4, 5, 6.5};
    assert_int_equal(p.n, 2);
    assert_memory_equal(p.xyz, want, sizeof want);
    assert_int_equal(p.frame, SM_POINTS_FRAME_LPS);
    assert_string_equal(p.kind, "Slicer .fcsv");
    assert_int_equal(sm_points_csv_line(fcsv, strlen(fcsv), p.header_line, 1), 5);
    char *out = format(&p);
    assert_non_null(strstr(out, "id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID,"
                                "inside\nvtkMRMLMarkupsFiducialNode_0,1,2,3,"));
    free(out);
    sm_points_to_frame(&p, SM_POINTS_FRAME_RAS);
    assert_true(p.xyz[0] == -1 && p.xyz[1] == -2 && p.xyz[2] == 3);
    sm_points_release(&p);
    /* the old Slicer frame code 0 is RAS; no CoordinateSystem: RAS too */
    p = parse_ok("# Markups fiducial file version = 4.6\n# CoordinateSystem = 0\n"
                 "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n"
                 "a,1,2,3,0,0,0,1,1,1,0,F-1,,\n");
    assert_int_equal(p.frame, SM_POINTS_FRAME_RAS);
    sm_points_to_frame(&p, SM_POINTS_FRAME_LPS);
    assert_true(p.xyz[0] == -1 && p.xyz[1] == -2 && p.xyz[2] == 3);
    sm_points_release(&p);

    const char *json =
        "{\"@schema\": \"markups-schema-v1.0.3.json#\", \"markups\": [{\"type\": \"Fiducial\", "
        "\"coordinateSystem\": \"RAS\", \"controlPoints\": [{\"id\": \"1\", \"label\": \"tip, "
        "\\\"L\\\"\", \"position\": [1.0, 2.0, 3.0]}, {\"label\": \"F-2\", \"position\": [4, 5, "
        "6.5]}]}]}";
    p = parse_ok(json);
    assert_int_equal(p.frame, SM_POINTS_FRAME_RAS);
    assert_memory_equal(p.xyz, want, sizeof want);
    assert_int_equal(sm_points_csv_line(json, strlen(json), p.header_line, 0), 0);
    out = format(&p);
    assert_string_equal(out, "label,x,y,z,inside\n\"tip, \"\"L\"\"\",1,2,3,0\n\"F-2\",4,5,6.5,1\n");
    free(out);
    sm_points_release(&p);
    /* one file with LPS and RAS markups: every point in LPS */
    p = parse_ok("{\"markups\": [{\"coordinateSystem\": \"RAS\", \"controlPoints\": [{\"position\": "
                 "[1, 2, 3]}]}, {\"coordinateSystem\": \"LPS\", \"controlPoints\": "
                 "[{\"position\": [1, 2, 3]}]}]}");
    assert_int_equal(p.frame, SM_POINTS_FRAME_LPS);
    double mixed[6] = {-1, -2, 3, 1, 2, 3};
    assert_memory_equal(p.xyz, mixed, sizeof mixed);
    sm_points_release(&p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_plain),
        cmocka_unit_test(test_refused),
        cmocka_unit_test(test_named_columns),
        cmocka_unit_test(test_slicer),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
