/* Reads and writes simgate's data streams in plain C (the example of docs/transports/dds.md,
   "Data streams"; run by DdsStreamsTest). Built from simgate_streams.idl alone.
   usage: dds_stream_client DOMAIN PARTITION XML pose TOPIC COUNT      prints "seq time x y z yaw" per sample
          dds_stream_client DOMAIN PARTITION XML json TOPIC COUNT      prints "seq time kind json" per sample
          dds_stream_client DOMAIN PARTITION XML image TOPIC COUNT     prints "seq time width height encoding step bytes
                                                                       R G B" (rgb8: the middle pixel) per Image
          dds_stream_client DOMAIN PARTITION XML velocity TOPIC V W    writes one Velocity command
          dds_stream_client DOMAIN PARTITION XML command TOPIC JSON    writes one JsonCommand
          dds_stream_client DOMAIN PARTITION XML catalog COUNT [S]     prints "topic type component" per alive entry
   Exit 0 when done, 3 when not all came within 60 s (catalog: S s). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dds/dds.h>
#include "simgate_streams.h" /* idlc simgate_streams.idl */

static int read_samples(dds_entity_t rd, const char* mode, int count, int seconds) {
  int got = 0; /* take and print until `count` samples, `seconds` at most */
  for (int i = 0; i < seconds * 100 && got < count; i++) {
    void* s[1] = {NULL};
    dds_sample_info_t si;
    while (got < count && dds_take(rd, s, &si, 1, 1) == 1) {
      if (si.valid_data && strcmp(mode, "pose") == 0) {
        const simgate_stream_Pose* p = s[0];
        printf("%llu %.6f %.6f %.6f %.6f %.6f\n", (unsigned long long)p->seq, p->time, p->x, p->y,
               p->z, p->yaw),
            got++;
      } else if (si.valid_data && strcmp(mode, "json") == 0) {
        const simgate_stream_JsonSample* j = s[0];
        printf("%llu %.6f %s %s\n", (unsigned long long)j->seq, j->time, j->kind, j->json), got++;
      } else if (si.valid_data && strcmp(mode, "image") == 0) {
        const simgate_stream_Image* m = s[0];
        unsigned r = 0, g = 0, b = 0;
        if (strcmp(m->encoding, "rgb8") == 0 && m->data._length >= m->step * m->height &&
            m->height > 0) {
          const unsigned char* px =
              m->data._buffer + (m->height / 2) * m->step + (m->width / 2) * 3;
          r = px[0], g = px[1], b = px[2];
        }
        printf("%llu %.6f %u %u %s %u %u %u %u %u\n", (unsigned long long)m->seq, m->time, m->width,
               m->height, m->encoding, m->step, m->data._length, r, g, b),
            got++;
      } else if (si.valid_data) {
        const simgate_stream_StreamEntry* e = s[0];
        printf("%s %s %s\n", e->topic, e->type_name, e->component), got++;
      }
      dds_return_loan(rd, s, 1);
    }
    fflush(stdout);
    if (got < count) dds_sleepfor(DDS_MSECS(10));
  }
  return got < count ? 3 : 0;
}

int main(int argc, char** argv) {
  if (argc < 6) return 2;
  dds_domainid_t domain = (dds_domainid_t)atoi(argv[1]);
  const char* mode = argv[4];
  dds_entity_t dom =
      dds_create_domain(domain, argv[3]); /* the simulation's network config (loopback) */
  dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  dds_qos_t* q = dds_create_qos();
  dds_qset_partition1(q, argv[2]); /* the simulation's partition */
  dds_entity_t sub = dds_create_subscriber(pp, q, NULL), pub = dds_create_publisher(pp, q, NULL);
  int rc = 2;
  if (strcmp(mode, "pose") == 0 || strcmp(mode, "json") == 0 ||
      strcmp(mode, "image") == 0) { /* sensors: best effort, latest sample */
    dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
    const dds_topic_descriptor_t* type = strcmp(mode, "pose") == 0 ? &simgate_stream_Pose_desc
                                         : strcmp(mode, "image") == 0
                                             ? &simgate_stream_Image_desc
                                             : &simgate_stream_JsonSample_desc;
    dds_entity_t rd =
        dds_create_reader(sub, dds_create_topic(pp, type, argv[5], NULL, NULL), q, NULL);
    rc = argc > 6 ? read_samples(rd, mode, atoi(argv[6]), 60) : 2;
  } else if (strcmp(mode, "catalog") == 0) { /* the catalog: reliable, transient-local */
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_entity_t rd = dds_create_reader(
        sub, dds_create_topic(pp, &simgate_stream_StreamEntry_desc, "simgate_Streams", NULL, NULL),
        q, NULL);
    rc = read_samples(rd, mode, atoi(argv[5]), argc > 6 ? atoi(argv[6]) : 60);
  } else if ((strcmp(mode, "velocity") == 0 && argc > 7) ||
             (strcmp(mode, "command") == 0 && argc > 6)) {
    int typed = strcmp(mode, "velocity") == 0; /* a command: reliable */
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    const dds_topic_descriptor_t* type =
        typed ? &simgate_stream_Velocity_desc : &simgate_stream_JsonCommand_desc;
    dds_entity_t wr =
        dds_create_writer(pub, dds_create_topic(pp, type, argv[5], NULL, NULL), q, NULL);
    dds_publication_matched_status_t m = {0}; /* wait (60 s at most) for the simulation's reader */
    for (int i = 0; i < 6000 && m.current_count == 0; i++, dds_sleepfor(DDS_MSECS(10)))
      dds_get_publication_matched_status(wr, &m);
    simgate_stream_Velocity v = {.v = atof(argv[6]), .w = typed ? atof(argv[7]) : 0};
    simgate_stream_JsonCommand c = {.json = argv[6]};
    rc = m.current_count == 0 ? 3
         : dds_write(wr, typed ? (void*)&v : (void*)&c) < 0 ||
                 dds_wait_for_acks(wr, DDS_SECS(30)) < 0
             ? 1
             : 0;
  }
  dds_delete_qos(q);
  dds_delete(dom > 0 ? dom : pp);
  return rc;
}
