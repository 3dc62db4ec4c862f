!> Checkpoint files: the whole state of a dynamic run in one binary file written with MPI-IO,
!> in global node and cell order, so a run can continue from it on any number of ranks. The
!> node and cell records are those of a field registry (iem_fields): a node's record is its
!> node fields' values in registration order, a cell's its cell fields', so what a checkpoint
!> holds is what the caller registered, and the file records that layout.
!> The format (version 6: header, energy slots, node records, cell records, checksum) and
!> the reader's checks of a file's header and checksum are iem_checkpoint_header's, whose
!> public names this module re-exports; this module writes and reads the records.
!> A file is written as <path>.tmp and renamed to <path> once complete, so a crash while
!> writing leaves the previous checkpoint intact.
module iem_checkpoint
  use, intrinsic :: iso_c_binding, only: c_int, c_char, c_null_char
  use, intrinsic :: iso_fortran_env, only: int8
  use iem_paths, only: mpiio_name
  use mpi_f08, only: MPI_Comm, MPI_File, MPI_Datatype, MPI_Comm_rank, &
                     MPI_Comm_size, MPI_File_open, MPI_File_close, MPI_File_set_view, &
                     MPI_File_write_at, MPI_File_read_at, MPI_File_write_all, MPI_File_read_all, &
                     MPI_Type_create_hindexed, MPI_Type_contiguous, MPI_Type_commit, &
                     MPI_Type_free, MPI_Bcast, &
                     MPI_Barrier, MPI_Allreduce, MPI_MAX, MPI_BXOR, MPI_INTEGER, MPI_INTEGER8, &
                     MPI_DOUBLE_PRECISION, MPI_MODE_CREATE, MPI_MODE_WRONLY, MPI_MODE_RDONLY, &
                     MPI_INFO_NULL, MPI_OFFSET_KIND, MPI_BYTE, MPI_ADDRESS_KIND, &
                     MPI_STATUS_IGNORE, &
                     MPI_IN_PLACE
  use iem_kinds, only: wp, i8
  use iem_exact_sum, only: exact_sum_t, exact_sum_packed_size
  use iem_fields, only: field_registry_t, centre_node, centre_cell
  use iem_word_hash, only: word_hash, words_hash, records_hash, text_hash
  use iem_checkpoint_header, only: checkpoint_header_t, checkpoint_read_header, &
                                   checkpoint_verify, checkpoint_magic, checkpoint_version, &
                                   energy_words, checkpoint_layout, checkpoint_check_layout, &
                                   header_bytes, n_header, layout_at, layout_room, record_sizes, &
                                   header_ints, header_reals, layout_words
  implicit none
  private
  public :: checkpoint_header_t, checkpoint_write, checkpoint_read_header, checkpoint_verify, &
            record_runs
  public :: checkpoint_read, checkpoint_magic, checkpoint_version, word_hash
  public :: checkpoint_layout, checkpoint_check_layout, energy_words

  !> Bytes of the buffer through which records are written and read (at least one record).
  integer(i8), parameter :: chunk_bytes = 2_i8**24

  interface
    function c_rename(old, new) bind(C, name='rename') result(r)
      import :: c_int, c_char
      character(kind=c_char), intent(in) :: old(*), new(*)
      integer(c_int) :: r
    end function c_rename
  end interface

contains

  !> The records of entities ents of a centre of reg, each padded to n words, as words(n, k).
  subroutine pack_records(reg, centre, ents, n, words)
    type(field_registry_t), intent(in) :: reg
    integer, intent(in) :: centre, ents(:), n
    integer(i8), intent(out) :: words(:, :)
    integer(int8), allocatable :: rec(:)
    integer :: k
    allocate(rec(8*n))
    rec = 0
    do k = 1, size(ents)
      call reg%pack_one(centre, ents(k), rec)
      words(:, k) = transfer(rec, 0_i8, n)
    end do
  end subroutine pack_records

  !> Set the entities ents of a centre of reg from the records words(n, k).
  subroutine unpack_records(reg, centre, ents, n, words)
    type(field_registry_t), intent(inout) :: reg
    integer, intent(in) :: centre, ents(:), n
    integer(i8), intent(in) :: words(:, :)
    integer :: k
    do k = 1, size(ents)
      call reg%unpack_one(centre, ents(k), transfer(words(:, k), 0_int8, 8*n))
    end do
  end subroutine unpack_records

  !> A rank's records as runs: record k of entity ents(k) at global index gids(k) (ascending),
  !> runs(:, r) = (first entity, first global index, count) of records whose entities and
  !> indices both follow each other (the form checkpoint_write and checkpoint_read take).
  pure function record_runs(ents, gids) result(runs)
    integer, intent(in) :: ents(:)
    integer(i8), intent(in) :: gids(:)
    integer(i8), allocatable :: runs(:, :)
    integer :: k, nr
    logical :: on(size(ents))
    do k = 1, size(ents)
      on(k) = k > 1
      if (on(k)) on(k) = ents(k) == ents(k - 1) + 1 .and. gids(k) == gids(k - 1) + 1
    end do
    allocate(runs(3, count(.not. on)))
    nr = 0
    do k = 1, size(ents)
      if (on(k)) then
        runs(3, nr) = runs(3, nr) + 1
      else
        nr = nr + 1
        runs(:, nr) = [int(ents(k), i8), gids(k), 1_i8]
      end if
    end do
  end function record_runs

  !> Write a checkpoint collectively: the header (with reg's record layout), this rank's
  !> (w_ext, w_damp), the node records of reg's node entities and the cell records of its
  !> cell entities given as runs (record_runs: entities at ascending global indices; each node
  !> and each cell written by one rank), with the checksum of the whole. stat /= 0 with msg
  !> on every rank on failure (the previous file at path intact). buffer_bytes: the records'
  !> buffer (default chunk_bytes; a test's smaller one makes several rounds).
  subroutine checkpoint_write(path, comm, h, energy, reg, node_runs, cell_runs, stat, msg, &
                              buffer_bytes)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(checkpoint_header_t), intent(in) :: h
    real(wp), intent(in) :: energy(energy_words)
    ! (not changed: inout only for move_records, which also reads)
    type(field_registry_t), intent(inout) :: reg
    integer(i8), intent(in) :: node_runs(:, :), cell_runs(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8), intent(in), optional :: buffer_bytes
    type(MPI_File) :: fh
    type(checkpoint_header_t) :: hc
    integer :: rank, ierr, ierr2, rec_n, rec_c
    integer(MPI_OFFSET_KIND) :: off_n, off_c
    integer(i8) :: sum
    character(len=:), allocatable :: tmp

    call MPI_Comm_rank(comm, rank)
    hc = h
    hc%rec_node = reg%record_bytes(centre_node)
    hc%rec_cell = reg%record_bytes(centre_cell)
    hc%layout = checkpoint_layout(reg)
    hc%layout_hash = text_hash(hc%layout)
    if (len(hc%layout) > layout_room) hc%layout = hc%layout(1:layout_room)
    call record_sizes(hc, rec_n, rec_c)
    stat = 0
    msg = ''
    off_n = header_bytes + 8_MPI_OFFSET_KIND*energy_words*hc%n_ranks
    off_c = off_n + 8_MPI_OFFSET_KIND*rec_n*hc%n_nodes
    tmp = path//'.tmp'
    call MPI_File_open(comm, mpiio_name(tmp), ior(MPI_MODE_CREATE, MPI_MODE_WRONLY), &
                       MPI_INFO_NULL, fh, ierr)
    call agree(ierr, 'cannot create '//tmp)
    if (stat /= 0) return
    ! the checksum: every rank hashes the words it writes (its energy slot and records; rank
    ! 0 also the header, its checksum word as 0, and the layout text and the zeros after it)
    call MPI_File_write_at(fh, header_bytes + 8_MPI_OFFSET_KIND*energy_words*rank, energy, &
                           energy_words, MPI_DOUBLE_PRECISION, MPI_STATUS_IGNORE, ierr)
    sum = words_hash(header_bytes/8 + int(energy_words, i8)*rank, &
                     transfer(energy, 0_i8, energy_words))
    call move_records(fh, comm, off_n, rec_n, reg, centre_node, node_runs, .true., sum, ierr2, &
                      buffer_bytes)
    ierr = max(ierr, ierr2)
    if (rec_c > 0) then
      call move_records(fh, comm, off_c, rec_c, reg, centre_cell, cell_runs, .true., sum, ierr2, &
                        buffer_bytes)
      ierr = max(ierr, ierr2)
    end if
    hc%checksum = 0
    if (rank == 0) then
      sum = ieor(sum, words_hash(0_i8, header_ints(hc)))
      sum = ieor(sum, words_hash(n_header, transfer(header_reals(hc), 0_i8, int(n_header))))
      sum = ieor(sum, words_hash(layout_at/8, layout_words(hc%layout)))
    end if
    call MPI_Allreduce(MPI_IN_PLACE, sum, 1, MPI_INTEGER8, MPI_BXOR, comm)
    hc%checksum = sum
    ! the header last, in the file's own view (the records' views set their own)
    call MPI_File_set_view(fh, 0_MPI_OFFSET_KIND, MPI_BYTE, MPI_BYTE, 'native', MPI_INFO_NULL, &
                           ierr2)
    ierr = max(ierr, ierr2)
    if (rank == 0) then
      call MPI_File_write_at(fh, 0_MPI_OFFSET_KIND, header_ints(hc), int(n_header), &
                             MPI_INTEGER8, MPI_STATUS_IGNORE, ierr2)
      ierr = max(ierr, ierr2)
      call MPI_File_write_at(fh, int(8*n_header, MPI_OFFSET_KIND), header_reals(hc), &
                             int(n_header), MPI_DOUBLE_PRECISION, MPI_STATUS_IGNORE, ierr2)
      ierr = max(ierr, ierr2)
      call MPI_File_write_at(fh, int(layout_at, MPI_OFFSET_KIND), layout_words(hc%layout), &
                             int(layout_room/8), MPI_INTEGER8, MPI_STATUS_IGNORE, ierr2)
      ierr = max(ierr, ierr2)
    end if
    call MPI_File_close(fh, ierr2)
    call agree(max(ierr, ierr2), 'writing '//tmp//' failed')
    if (stat /= 0) return
    call MPI_Barrier(comm)
    ierr = 0
    if (rank == 0) ierr = c_rename(tmp//c_null_char, path//c_null_char)
    call MPI_Bcast(ierr, 1, MPI_INTEGER, 0, comm)
    if (ierr /= 0) then
      stat = 1
      msg = 'cannot rename '//tmp//' to '//path
    end if

  contains

    subroutine agree(e, what)
      integer, intent(in) :: e
      character(len=*), intent(in) :: what
      integer :: worst
      call MPI_Allreduce(e, worst, 1, MPI_INTEGER, MPI_MAX, comm)
      if (worst /= 0) then
        stat = 1
        msg = 'checkpoint: '//what
      end if
    end subroutine agree
  end subroutine checkpoint_write

  !> Read the node and cell records given as runs (record_runs: reg's entities at ascending
  !> global indices; the file's layout is reg's: checkpoint_check_layout) into reg, and this
  !> rank's (w_ext, w_damp): its own when the file was written on as many ranks, else the
  !> totals on rank 0 and zeros elsewhere; buffer_bytes as checkpoint_write's. Collective.
  subroutine checkpoint_read(path, comm, h, energy, reg, node_runs, cell_runs, stat, msg, &
                             buffer_bytes)
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    type(checkpoint_header_t), intent(in) :: h
    real(wp), intent(out) :: energy(energy_words)
    type(field_registry_t), intent(inout) :: reg
    integer(i8), intent(in) :: node_runs(:, :), cell_runs(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8), intent(in), optional :: buffer_bytes
    type(MPI_File) :: fh
    integer :: rank, n_ranks, ierr, ierr2, rec_n, rec_c, worst, r, q
    integer(MPI_OFFSET_KIND) :: off_n, off_c
    real(wp), allocatable :: all_slots(:, :)
    type(exact_sum_t) :: total(2), one
    integer(i8) :: packed(exact_sum_packed_size), unused
    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, n_ranks)
    call record_sizes(h, rec_n, rec_c)
    stat = 0
    msg = ''
    energy = 0.0_wp
    call MPI_File_open(comm, mpiio_name(path), MPI_MODE_RDONLY, MPI_INFO_NULL, fh, ierr)
    call MPI_Allreduce(ierr, worst, 1, MPI_INTEGER, MPI_MAX, comm)
    if (worst /= 0) then
      stat = 1
      msg = 'cannot open '//path
      return
    end if
    ierr = 0
    if (h%n_ranks == n_ranks) then
      call MPI_File_read_at(fh, header_bytes + 8_MPI_OFFSET_KIND*energy_words*rank, energy, &
                            energy_words, MPI_DOUBLE_PRECISION, MPI_STATUS_IGNORE, ierr)
    else if (rank == 0) then
      ! another rank count: rank 0 takes the exact sum of every writer's accumulators
      allocate(all_slots(energy_words, h%n_ranks))
      call MPI_File_read_at(fh, header_bytes, all_slots, energy_words*int(h%n_ranks), &
                            MPI_DOUBLE_PRECISION, MPI_STATUS_IGNORE, ierr)
      do q = 1, 2
        call total(q)%reset()
        do r = 1, int(h%n_ranks)
          packed = int(all_slots((q - 1)*exact_sum_packed_size + 1:q*exact_sum_packed_size, &
                                 r), i8)
          call one%unpack(packed)
          call total(q)%merge(one)
        end do
        call total(q)%pack(packed)
        energy((q - 1)*exact_sum_packed_size + 1:q*exact_sum_packed_size) = real(packed, wp)
      end do
    end if
    off_n = header_bytes + 8_MPI_OFFSET_KIND*energy_words*h%n_ranks
    off_c = off_n + 8_MPI_OFFSET_KIND*rec_n*h%n_nodes
    call move_records(fh, comm, off_n, rec_n, reg, centre_node, node_runs, .false., unused, ierr2, &
                      buffer_bytes)
    ierr = max(ierr, ierr2)
    if (rec_c > 0) then
      call move_records(fh, comm, off_c, rec_c, reg, centre_cell, cell_runs, .false., unused, &
                        ierr2, buffer_bytes)
      ierr = max(ierr, ierr2)
    end if
    call MPI_File_close(fh, ierr2)
    call MPI_Allreduce(max(ierr, ierr2), worst, 1, MPI_INTEGER, MPI_MAX, comm)
    if (worst /= 0) then
      stat = 1
      msg = 'reading '//path//' failed'
    end if
  end subroutine checkpoint_read

  !> Collective write (or read) of the records of reg's entities of a centre given as runs
  !> (record_runs: entities at ascending global indices of the record array at byte offset
  !> off, n words a record), through a buffer of at most buffer_bytes (default chunk_bytes; in
  !> as many rounds on every rank as the rank with the most records needs; each round's
  !> entities and indices listed for it alone). Writing, sum XORs in the hashes of the words
  !> written.
  subroutine move_records(fh, comm, off, n, reg, centre, runs, write, sum, ierr, buffer_bytes)
    type(MPI_File), intent(inout) :: fh
    type(MPI_Comm), intent(in) :: comm
    integer(MPI_OFFSET_KIND), intent(in) :: off
    integer, intent(in) :: n, centre
    type(field_registry_t), intent(inout) :: reg
    integer(i8), intent(in) :: runs(:, :)
    logical, intent(in) :: write
    integer(i8), intent(inout) :: sum
    integer, intent(out) :: ierr
    integer(i8), intent(in), optional :: buffer_bytes
    integer(i8), allocatable :: buf(:, :), gids(:)
    integer, allocatable :: ents(:)
    integer(i8) :: total, taken, room
    integer :: m, rounds, r, k, e, run
    total = 0
    if (size(runs, 2) > 0) total = sum_of(runs(3, :))
    room = chunk_bytes
    if (present(buffer_bytes)) room = buffer_bytes
    m = int(max(1_i8, min(room/(8_i8*n), total)))
    rounds = int((total + m - 1)/m)
    call MPI_Allreduce(MPI_IN_PLACE, rounds, 1, MPI_INTEGER, MPI_MAX, comm)
    allocate(buf(n, m), ents(m), gids(m), stat=ierr)
    if (ierr /= 0) then
      ! (out of memory: this rank moves nothing, but takes part in every round)
      if (allocated(buf)) deallocate(buf)
      if (allocated(ents)) deallocate(ents)
      if (allocated(gids)) deallocate(gids)
      allocate(buf(n, 0), ents(0), gids(0))
    end if
    ! (the next record: its run and how many of that run are taken)
    run = 1
    taken = 0
    do r = 1, rounds
      k = 0
      do while (k < m .and. run <= size(runs, 2) .and. ierr == 0)
        k = k + 1
        ents(k) = int(runs(1, run) + taken)
        gids(k) = runs(2, run) + taken
        taken = taken + 1
        if (taken == runs(3, run)) then
          run = run + 1
          taken = 0
        end if
      end do
      if (write) then
        call pack_records(reg, centre, ents(1:k), n, buf(:, 1:k))
        sum = ieor(sum, records_hash(off/8, n, gids(1:k), buf(:, 1:k)))
      end if
      call transfer_records(fh, off, n, gids(1:k), buf(:, 1:k), write, e)
      ierr = max(ierr, e)
      if (.not. write) call unpack_records(reg, centre, ents(1:k), n, buf(:, 1:k))
    end do
  contains
    !> The sum of the runs' counts.
    pure integer(i8) function sum_of(counts)
      integer(i8), intent(in) :: counts(:)
      integer :: j
      sum_of = 0
      do j = 1, size(counts)
        sum_of = sum_of + counts(j)
      end do
    end function sum_of
  end subroutine move_records

  !> Collective write (or read) of records rec(:, k) of n words at the global indices
  !> gids(k) (ascending) of the record array that starts at byte offset off.
  subroutine transfer_records(fh, off, n, gids, rec, write, ierr)
    type(MPI_File), intent(inout) :: fh
    integer(MPI_OFFSET_KIND), intent(in) :: off
    integer, intent(in) :: n
    integer(i8), intent(in) :: gids(:)
    integer(i8), intent(inout) :: rec(:, :)
    logical, intent(in) :: write
    integer, intent(out) :: ierr
    integer, allocatable :: lens(:)
    integer(MPI_ADDRESS_KIND), allocatable :: disp(:)
    type(MPI_Datatype) :: view, record
    integer :: k, runs, e
    ! one record (n words) is the unit of the view and of the count, so that no count exceeds
    ! the number of records of this rank (n times it may pass 2^31)
    call MPI_Type_contiguous(n, MPI_INTEGER8, record, ierr)
    call MPI_Type_commit(record, e)
    ierr = max(ierr, e)
    ! contiguous runs of global indices
    allocate(lens(size(gids)), disp(size(gids)))
    runs = 0
    do k = 1, size(gids)
      if (k > 1) then
        if (gids(k) == gids(k - 1) + 1) then
          lens(runs) = lens(runs) + 1
          cycle
        end if
      end if
      runs = runs + 1
      lens(runs) = 1
      disp(runs) = int(gids(k), MPI_ADDRESS_KIND)*8*n
    end do
    call MPI_Type_create_hindexed(runs, lens(1:runs), disp(1:runs), record, view, e)
    ierr = max(ierr, e)
    call MPI_Type_commit(view, e)
    ierr = max(ierr, e)
    call MPI_File_set_view(fh, off, record, view, 'native', MPI_INFO_NULL, e)
    ierr = max(ierr, e)
    if (write) then
      call MPI_File_write_all(fh, rec, size(gids), record, MPI_STATUS_IGNORE, e)
    else
      call MPI_File_read_all(fh, rec, size(gids), record, MPI_STATUS_IGNORE, e)
    end if
    ierr = max(ierr, e)
    call MPI_Type_free(view, e)
    ierr = max(ierr, e)
    call MPI_Type_free(record, e)
    ierr = max(ierr, e)
  end subroutine transfer_records
end module iem_checkpoint
