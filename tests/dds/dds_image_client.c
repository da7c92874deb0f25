/* A simgate DDS client in plain C that gets the images of its replies raw (the example of
   docs/transports/dds.md, "Images raw"; run by DdsProcessTest).
   usage: dds_image_client DOMAIN PARTITION XML COMPONENT SERVICE PARAMS_JSON
   prints "REPLY <SUCCESS|FAILED> <result>", then one line per image of that call:
   "IMAGE seq time width height encoding step bytes R G B" (R G B: the middle pixel, rgb8). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dds/dds.h>
#include "simgate_dds.h"     /* idlc simgate_dds.idl */
#include "simgate_streams.h" /* idlc simgate_streams.idl: simgate_stream_Image */

static int count_raw(const char* result) { /* the records whose pixels come raw */
  int n = 0;
  for (const char* p = result; (p = strstr(p, "\"format\":\"raw\"")) != NULL; p++) n++;
  return n;
}

int main(int argc, char** argv) {
  if (argc < 7) return 2;
  dds_domainid_t domain = (dds_domainid_t)atoi(argv[1]);
  dds_entity_t dom = dds_create_domain(domain, argv[3]);
  dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  dds_qos_t *q = dds_create_qos(), *part_qos = dds_create_qos();
  dds_qset_partition1(q, argv[2]);
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  dds_entity_t wr = dds_create_writer(
      dds_create_publisher(pp, q, NULL),
      dds_create_topic(pp, &simgate_Request_desc, "simgate_Request", NULL, NULL), q, NULL);
  dds_guid_t me; /* our id: the request writer's GUID */
  dds_get_guid(wr, &me);
  char ud[64] = "simgate.id=", part[400];
  for (int i = 0; i < 16; i++) sprintf(ud + 11 + 2 * i, "%02x", me.v[i]);
  dds_qset_userdata(q, ud, strlen(ud)); /* both readers announce our id */
  snprintf(part, sizeof part, "%s/%s", argv[2], ud + 11), dds_qset_partition1(part_qos, part);
  dds_entity_t sub = dds_create_subscriber(pp, part_qos, NULL);
  /* the image reader first, then the reply reader: when the server has our reply reader, it
     has our image reader too, and sends the images of our replies raw */
  dds_entity_t images = dds_create_reader(
      sub, dds_create_topic(pp, &simgate_stream_Image_desc, "simgate_ReplyImage", NULL, NULL), q,
      NULL);
  dds_entity_t rd = dds_create_reader(
      sub, dds_create_topic(pp, &simgate_Reply_desc, "simgate_Reply", NULL, NULL), q, NULL);
  dds_publication_matched_status_t m = {0}; /* the simulation's request reader (10 s at most) */
  for (int i = 0; i < 1000 && m.current_count == 0; i++, dds_sleepfor(DDS_MSECS(10)))
    dds_get_publication_matched_status(wr, &m);
  if (m.current_count == 0) {
    fprintf(stderr, "no simgate found within 10 s\n");
    dds_delete(dom > 0 ? dom : pp);
    return 3;
  }
  simgate_Request rq = {
      .op = simgate_OP_CALL, .component = argv[4], .service = argv[5], .params = argv[6]};
  memcpy(rq.id.client, me.v, 16);
  rq.id.seq = 1;
  dds_write(wr, &rq);
  /* the final reply of seq 1, and as many images of seq 1 as its records say are raw (the
     two topics are not ordered with each other: either may come first) */
  int status = -1, expected = -1, got = 0;
  char* lines = calloc(1, 1);
  size_t lines_len = 0;
  for (int i = 0; i < 6000 && (status < 0 || got < expected); i++, dds_sleepfor(DDS_MSECS(10))) {
    void* s[1] = {NULL};
    dds_sample_info_t si;
    while (status < 0 && dds_take(rd, s, &si, 1, 1) == 1) {
      const simgate_Reply* r = s[0];
      if (si.valid_data && r->seq == 1 && r->last) {
        printf("REPLY %s %s%s\n", r->status == simgate_ST_SUCCESS ? "SUCCESS" : "FAILED", r->result,
               r->message);
        status = r->status == simgate_ST_SUCCESS ? 0 : 1;
        expected = count_raw(r->result);
      }
      dds_return_loan(rd, s, 1);
    }
    while (dds_take(images, s, &si, 1, 1) == 1) {
      const simgate_stream_Image* im = s[0];
      if (si.valid_data && im->seq == 1) {
        unsigned r = 0, g = 0, b = 0;
        size_t mid = (size_t)(im->height / 2) * im->step + (size_t)(im->width / 2) * 3;
        if (strcmp(im->encoding, "rgb8") == 0 && mid + 2 < im->data._length)
          r = im->data._buffer[mid], g = im->data._buffer[mid + 1], b = im->data._buffer[mid + 2];
        char line[400];
        int n = snprintf(line, sizeof line, "IMAGE %llu %.17g %u %u %s %u %u %u %u %u\n",
                         (unsigned long long)im->seq, im->time, im->width, im->height, im->encoding,
                         im->step, im->data._length, r, g, b);
        lines = realloc(lines, lines_len + (size_t)n + 1);
        memcpy(lines + lines_len, line, (size_t)n + 1);
        lines_len += (size_t)n;
        got++;
      }
      dds_return_loan(images, s, 1);
    }
  }
  fputs(lines, stdout);
  free(lines);
  if (status < 0)
    fprintf(stderr, "no reply from simgate within 60 s\n");
  else if (got < expected)
    fprintf(stderr, "%d of %d images within 60 s\n", got, expected);
  dds_delete_qos(q), dds_delete_qos(part_qos);
  dds_delete(dom > 0 ? dom : pp);
  return status < 0 || got < expected ? 3 : status;
}
