!> Repartitioning during a run: a new partition (the weighted coordinate bisection of
!> iem_decomposition with new node weights), the lattice and halo plan built for it, and every
!> registered field moved with its node or cell (migrate). Values travel as bytes, so they
!> arrive bitwise; each rank places what it receives by global number in the new lattice's
!> order. After a migration the halo columns of node fields are zero: the caller refreshes
!> those it needs (the state) with its halo exchange, and rebuilds whatever it derived from
!> the old lattice.
module iem_migration
  use, intrinsic :: iso_fortran_env, only: int8
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Datatype, MPI_Alltoall, &
                     MPI_Alltoallv, MPI_Type_contiguous, MPI_Type_commit, MPI_Type_free, &
                     MPI_BYTE, MPI_INTEGER, MPI_Allreduce, MPI_IN_PLACE, MPI_MAX
  use iem_kinds, only: wp, ip, i8
  use iem_body, only: body_t
  use iem_body_numbering, only: node_weight
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_rcb, only: rcb_t
  use iem_fields, only: field_registry_t, centre_node, centre_cell
  use iem_decomposition, only: decompose
  use iem_alloc_guard, only: alloc_guard_t
  implicit none
  private
  public :: migrate, repartition

  !> Bytes of the global number that heads every record in transit.
  integer, parameter :: gid_bytes = storage_size(1_i8)/8

contains

  !> Recompute the partition and move everything to it: the weighted bisection of the body's
  !> nodes with the node weights weight(x, y) (without: the body's own partition, see
  !> decompose), the ranks' parts in proportion to share(0:P-1) when given; lat and halo are
  !> replaced by the new lattice and halo plan (width values a node, default the old plan's),
  !> every field of reg is migrated (see migrate). Collective.
  !> stat /= 0 with msg on every rank when it fails: lat, halo and reg are then unchanged,
  !> except after a failure inside the migration itself (reg is then undefined).
  subroutine repartition(body, comm, lat, halo, reg, stat, msg, weight, width, share)
    type(body_t), intent(in) :: body
    type(MPI_Comm), intent(in) :: comm
    type(local_lattice_t), intent(inout) :: lat
    type(halo_t), intent(inout) :: halo
    type(field_registry_t), intent(inout) :: reg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    procedure(node_weight), optional :: weight
    integer, intent(in), optional :: width
    real(wp), intent(in), optional :: share(0:)
    integer(ip), allocatable :: owner(:)
    type(local_lattice_t) :: lat2
    type(halo_t) :: halo2
    type(rcb_t) :: bis
    integer :: w, l, ij(2)

    w = halo%width
    if (present(width)) w = width
    call decompose(body, comm, lat2, halo2, stat, msg, w, weight=weight, rcb=bis, share=share)
    if (stat /= 0) return
    ! the new owner of every node of the old lattice
    allocate(owner(lat%n_local))
    do l = 1, lat%n_local
      ij = lat%node_ij(l)
      owner(l) = int(bis%owner(ij(1), ij(2)), ip)
    end do
    call migrate(lat, lat2, owner, reg, comm, stat, msg)
    if (stat /= 0) return
    call lat%free()
    lat = lat2
    call halo%free()
    halo = halo2
  end subroutine repartition

  !> Move every field of reg from the lattice old to the lattice new, where owner(l) is the
  !> new owner of node l of old (owned and halo): each owned node's record goes to its new
  !> owner, each cell's record from the rank that counted it to every rank that holds the
  !> cell in new (the new owners of its corners); each arrives at its global number's place
  !> in new. reg must span old (its node and cell counts) and then spans new; node fields'
  !> halo columns are zero. Collective. stat /= 0 with msg on every rank when it fails (out
  !> of memory, or a lattice that does not match owner: a record not expected or one missing).
  subroutine migrate(old, new, owner, reg, comm, stat, msg)
    type(local_lattice_t), intent(in) :: old, new
    integer(ip), intent(in) :: owner(:)
    type(field_registry_t), intent(inout) :: reg
    type(MPI_Comm), intent(in) :: comm
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg

    stat = 0
    msg = ''
    if (reg%n_of(centre_node) /= old%n_local .or. reg%n_of(centre_cell) /= old%n_cells .or. &
        size(owner) /= old%n_local) stat = 1
    call MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, comm)
    if (stat /= 0) then
      msg = 'migrate: the fields and owners do not span the old lattice (nodes and cells)'
      return
    end if
    call move_centre(old, new, owner, reg, comm, centre_node, stat, msg)
    if (stat /= 0) return
    call move_centre(old, new, owner, reg, comm, centre_cell, stat, msg)
  end subroutine migrate

  !> Migrate the fields of one centre: count, exchange counts, pack (global number, record)
  !> grouped by destination, one MPI_Alltoallv in records (a contiguous type of the record's
  !> bytes, so counts stay small), place by global number.
  subroutine move_centre(old, new, owner, reg, comm, centre, stat, msg)
    type(local_lattice_t), intent(in) :: old, new
    integer(ip), intent(in) :: owner(:)
    type(field_registry_t), intent(inout) :: reg
    type(MPI_Comm), intent(in) :: comm
    integer, intent(in) :: centre
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer, allocatable :: scount(:), rcount(:), sdispl(:), rdispl(:), pos(:)
    integer(int8), allocatable :: sbuf(:), rbuf(:)
    logical, allocatable :: filled(:)
    integer(i8) :: rec, o, g, nsend, nrecv
    integer :: nranks, rank, r, l, c, k, e, n_new, n_expected, ierr, bad
    integer :: dest(4), nd
    type(MPI_Datatype) :: rtype
    type(alloc_guard_t) :: guard
    character(len=5) :: what

    what = merge('nodes', 'cells', centre == centre_node)
    n_new = merge(new%n_local, new%n_cells, centre == centre_node)
    if (.not. reg%has_centre(centre)) then
      ! nothing to move (every rank registered the same fields): only the count changes
      call reg%reset(centre, n_new, stat)
      return
    end if
    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, nranks)
    rec = gid_bytes + reg%record_bytes(centre)
    allocate(scount(0:nranks - 1), rcount(0:nranks - 1), sdispl(0:nranks - 1), &
             rdispl(0:nranks - 1), pos(0:nranks - 1))
    scount = 0
    if (centre == centre_node) then
      do l = 1, old%n_owned
        r = owner(l)
        scount(r) = scount(r) + 1
      end do
    else
      do c = 1, old%n_cells
        if (.not. old%cell_counted(c)) cycle
        call destinations(c, dest, nd)
        scount(dest(1:nd)) = scount(dest(1:nd)) + 1
      end do
    end if
    call MPI_Alltoall(scount, 1, MPI_INTEGER, rcount, 1, MPI_INTEGER, comm)
    ! records are counted in default integers: a rank holds fewer than huge(1) entities
    nsend = sum(int(scount, i8))
    nrecv = sum(int(rcount, i8))
    sdispl(0) = 0
    rdispl(0) = 0
    do r = 1, nranks - 1
      sdispl(r) = sdispl(r - 1) + scount(r - 1)
      rdispl(r) = rdispl(r - 1) + rcount(r - 1)
    end do
    allocate(sbuf(rec*nsend), stat=ierr)
    call guard%note(ierr, 'the send buffer of the migration', real(rec*nsend, wp))
    if (.not. guard%failed) then
      allocate(rbuf(rec*nrecv), stat=ierr)
      call guard%note(ierr, 'the receive buffer of the migration', real(rec*nrecv, wp))
    end if
    call guard%agree(comm, 'migrate', stat, msg)
    if (stat /= 0) return

    pos = sdispl
    if (centre == centre_node) then
      do l = 1, old%n_owned
        r = owner(l)
        call put(r, old%node_gid(l), l)
      end do
    else
      do c = 1, old%n_cells
        if (.not. old%cell_counted(c)) cycle
        call destinations(c, dest, nd)
        do k = 1, nd
          call put(dest(k), old%cell_gid(c), c)
        end do
      end do
    end if
    call MPI_Type_contiguous(int(rec), MPI_BYTE, rtype)
    call MPI_Type_commit(rtype)
    call MPI_Alltoallv(sbuf, scount, sdispl, rtype, rbuf, rcount, rdispl, rtype, comm)
    call MPI_Type_free(rtype)
    deallocate(sbuf)

    call reg%reset(centre, n_new, ierr)
    call guard%note(ierr, 'the fields on the new lattice', &
                    real(n_new, wp)*(rec - gid_bytes))
    call guard%agree(comm, 'migrate', stat, msg)
    if (stat /= 0) return
    allocate(filled(n_new))
    filled = .false.
    bad = 0
    do k = 1, int(nrecv)
      o = (k - 1)*rec
      g = transfer(rbuf(o + 1:o + gid_bytes), g)
      if (centre == centre_node) then
        e = new%local_of(g)
      else
        e = new%cell_local_of(g)
      end if
      if (e == 0) then
        bad = 1
        cycle
      end if
      if (filled(e)) then
        bad = 1
        cycle
      end if
      call reg%unpack_one(centre, e, rbuf(o + gid_bytes + 1:o + rec))
      filled(e) = .true.
    end do
    n_expected = merge(new%n_owned, new%n_cells, centre == centre_node)
    if (count(filled) /= n_expected) bad = 1
    call MPI_Allreduce(MPI_IN_PLACE, bad, 1, MPI_INTEGER, MPI_MAX, comm)
    if (bad /= 0) then
      stat = 1
      msg = 'migrate: the records of the '//what//' do not match the new lattice (a '// &
            'lattice not built for the owners given?)'
    end if

  contains

    !> Distinct new owners of the corners of old local cell cc (the ranks that will hold it).
    subroutine destinations(cc, d, m)
      integer, intent(in) :: cc
      integer, intent(out) :: d(4), m
      integer :: q, rq
      m = 0
      do q = 1, 4
        rq = owner(old%cell_nodes(q, cc))
        if (any(d(1:m) == rq)) cycle
        m = m + 1
        d(m) = rq
      end do
    end subroutine destinations

    !> Append the record (global number gg, entity ee of the old lattice) for rank rr.
    subroutine put(rr, gg, ee)
      integer, intent(in) :: rr, ee
      integer(i8), intent(in) :: gg
      integer(i8) :: oo
      oo = int(pos(rr), i8)*rec
      sbuf(oo + 1:oo + gid_bytes) = transfer(gg, 0_int8, gid_bytes)
      call reg%pack_one(centre, ee, sbuf(oo + gid_bytes + 1:oo + rec))
      pos(rr) = pos(rr) + 1
    end subroutine put
  end subroutine move_centre
end module iem_migration
