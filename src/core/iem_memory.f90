!> Memory a run needs on each rank, estimated before anything is allocated, and the memory the
!> ranks of one node can have (MemAvailable, capped by the cgroup's limit), compared before the
!> set-up allocates anything. Only the problem-sized arrays are counted: the program and its
!> libraries (about 25 MB a rank) are already resident, and so already left out of MemAvailable.
module iem_memory
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Comm_split_type, &
                     MPI_Comm_free, MPI_COMM_TYPE_SHARED, MPI_INFO_NULL, MPI_Allreduce, &
                     MPI_Bcast, MPI_SUM, MPI_MIN, MPI_MAXLOC, MPI_2DOUBLE_PRECISION, MPI_IN_PLACE
  use iem_kinds, only: wp, i8, mpi_wp
  use iem_strings, only: itoa
  implicit none
  private
  public :: memory_case_t, memory_need_t, memory_estimate, node_available_bytes, memory_check
  public :: bytes_text, approx_text

  !> Bytes of the arrays every run holds, per local node or cell (the values behind the
  !> estimate; docs/benchmarks.md has the measured totals).
  !> The lattice: its owned nodes' numbers and grid indices and its cells' numbers are runs
  !> along the grid rows, its cells' corners chunks listed only where their node rows are
  !> not consecutive (none a node or cell; the few halo nodes and the cells beside them are
  !> not counted); a cell's material (only with several materials; counted always) and open
  !> edges.
  real(wp), parameter, public :: lattice_node_bytes = 0.0_wp
  real(wp), parameter, public :: lattice_cell_bytes = 5.0_wp
  real(wp), parameter, public :: model_node_bytes = 24.0_wp    ! lumped mass, summed forces (2)
  !> Velocity Verlet with 4 values a node sums the forces into its rates array: no forces.
  real(wp), parameter :: verlet_forces_bytes = 16.0_wp
  !> A frame's buffer per node: none (its fields go through one buffer of 32768 nodes, 512 kB,
  !> a slab at a time; iem_h5_output_frames).
  real(wp), parameter, public :: frame_node_bytes = 0.0_wp
  !> Dynamic relaxation's work arrays (ten (2, n) and one (4, n)).
  real(wp), parameter, public :: relax_node_bytes = 192.0_wp
  !> Decomposition, on every rank, per node of its share: the rank's cell list (int64 a
  !> cell), its node map (8), and for a body cut by shapes or an image the strip and window
  !> maps and the bisection's points (about 32).
  real(wp), parameter, public :: decomp_cell_bytes = 8.0_wp, decomp_node_bytes = 40.0_wp
  !> Fracture state of a cell (iem_fracture's fracture_t).
  real(wp), parameter :: fracture_cell_bytes = 236.0_wp
  !> Nonlinear springs: 12 a cell, each 48 bytes plus 16 a reversal point of its history.
  integer, parameter :: springs_per_cell = 12

  !> What the estimate depends on.
  type :: memory_case_t
    !> Nodes and cells of the whole body.
    integer(i8) :: n_nodes = 0, n_cells = 0
    integer :: n_ranks = 1
    !> State values a node: 4, or 6 with capped damping.
    integer :: n_state = 4
    !> 'rk4', 'verlet' or 'static'.
    character(len=8) :: integrator = 'rk4'
    logical :: nonlinear = .false.
    !> Reversal points kept per nonlinear spring.
    integer :: depth = 8
    !> Whether the cells keep a fracture state (docs/model.md, "Fracture").
    logical :: fracture = .false.
    !> Whether mass damping keeps its powers and folded work a node (16 bytes), stiffness
    !> damping a cell.
    logical :: mass_damping = .false., stiffness_damping = .false.
  end type memory_case_t

  !> Estimated peak bytes of each rank (every rank holds its share only), in the set-up
  !> (decomposition) and in the run (lattice, model, state, nonlinear springs, output and
  !> checkpoint buffers).
  type :: memory_need_t
    real(wp) :: setup = 0.0_wp, run = 0.0_wp
    !> Bytes per node of the rank's share, in the set-up and in the run.
    real(wp) :: setup_per_node = 0.0_wp, run_per_node = 0.0_wp
  contains
    procedure :: peak => memory_need_peak
    procedure :: what => memory_need_what
  end type memory_need_t

contains

  !> Estimated peak bytes per rank of a run (pure: the same on every rank and in tests).
  pure function memory_estimate(mc) result(need)
    type(memory_case_t), intent(in) :: mc
    type(memory_need_t) :: need
    real(wp) :: nn, nc, n, c, ns, state, spring, ckpt, decomp, per_node, cells_per_node
    nn = real(mc%n_nodes, wp)
    nc = real(mc%n_cells, wp)
    n = nn/mc%n_ranks
    c = nc/mc%n_ranks
    cells_per_node = nc/max(nn, 1.0_wp)
    ns = real(mc%n_state, wp)
    select case (trim(mc%integrator))
    case ('static')
      state = 8.0_wp*(ns + (ns - 2.0_wp)) + relax_node_bytes
    case ('verlet')
      state = 8.0_wp*(ns + (ns - 2.0_wp))
      if (mc%n_state == 4) state = state - verlet_forces_bytes
    case default
      ! (fused RK4, 4 values a node, keeps no rates array)
      state = 8.0_wp*3.0_wp*ns
      if (mc%n_state /= 4) state = state + 8.0_wp*(ns - 2.0_wp)
    end select
    ! resident through the run, per local node (cells converted to nodes)
    per_node = lattice_node_bytes + model_node_bytes + state + lattice_cell_bytes*cells_per_node
    ! mass damping: each node's power and its folded work (model_t's pw_node, wd_node)
    if (mc%mass_damping .and. trim(mc%integrator) /= 'static') per_node = per_node + 16.0_wp
    if (mc%stiffness_damping .and. trim(mc%integrator) /= 'static') &
      per_node = per_node + 16.0_wp*cells_per_node
    spring = 0.0_wp
    ! nonlinear springs: the history (48 B and the stack), per cell 8 B, and their curves
    ! (48 B and the 8 B of the unused column that staggers them in the cache) where trial
    ! evaluations come between commits (not with velocity Verlet)
    if (mc%nonlinear) then
      spring = springs_per_cell*(48.0_wp + 16.0_wp*mc%depth) + 8.0_wp
      if (trim(mc%integrator) /= 'verlet') spring = spring + springs_per_cell*56.0_wp
    end if
    ! fracture: 12 largest strains, 8 failure times, the dissipation, 8 last strains, a flag
    if (mc%fracture) spring = spring + fracture_cell_bytes
    per_node = per_node + spring*cells_per_node
    ! a checkpoint (dynamic runs: at its interval or on a signal) packs the records of the
    ! checkpointed fields (the state y, rates acc and reactions of every node, the springs'
    ! history of every cell) round by round into a buffer (at most 16 MB: counted per node,
    ! which is the case up to about 3e5 nodes a rank and errs high beyond) with each round's
    ! entities, global numbers and the runs of its file view (24 bytes a record), from the
    ! run's own arrays (its registry borrows them; fused RK4's rates are zeros) but for the
    ! reactions (2 values a node), which it copies
    ckpt = 0.0_wp
    if (trim(mc%integrator) /= 'static') then
      ckpt = 8.0_wp*2.0_wp*ns + 24.0_wp + 16.0_wp
      if (mc%mass_damping) ckpt = ckpt + 8.0_wp
      if (mc%stiffness_damping) ckpt = ckpt + 8.0_wp*cells_per_node
      if (mc%nonlinear) ckpt = ckpt + &
        8.0_wp*springs_per_cell*(7.0_wp + 2.0_wp*mc%depth)*cells_per_node
      if (mc%fracture) ckpt = ckpt + 8.0_wp*29.0_wp*cells_per_node
    end if
    per_node = per_node + max(frame_node_bytes, ckpt)
    need%run_per_node = per_node
    need%run = per_node*n
    ! decomposition (coordinate bisection): the rank's lattice, its maps and, for a cut body,
    ! its strip and window; no array over the whole body on any rank
    decomp = (lattice_node_bytes + decomp_node_bytes + (lattice_cell_bytes + &
              decomp_cell_bytes)*cells_per_node)*n
    need%setup = decomp
    need%setup_per_node = decomp/max(n, 1.0_wp)
  end function memory_estimate

  !> Peak bytes of a rank.
  pure real(wp) function memory_need_peak(this) result(b)
    class(memory_need_t), intent(in) :: this
    b = max(this%setup, this%run)
  end function memory_need_peak

  !> What makes a rank's peak, with its bytes per node, for messages.
  function memory_need_what(this) result(s)
    class(memory_need_t), intent(in) :: this
    character(len=:), allocatable :: s
    if (this%setup > this%run) then
      s = 'set-up of the lattice, '//bytes_text(this%setup_per_node)//'/node of its share'
    else
      s = 'lattice, state and buffers, '//bytes_text(this%run_per_node)//'/node of its share'
    end if
  end function memory_need_what

  !> Bytes this node can still give: MemAvailable of /proc/meminfo, capped by the headroom of
  !> this process's memory cgroup and of every cgroup above it (v2 memory.max, v1
  !> memory.limit_in_bytes, less the usage that cannot be reclaimed: usage less inactive file
  !> pages); -1 where /proc/meminfo cannot be read.
  function node_available_bytes() result(avail)
    real(wp) :: avail
    real(wp) :: kb, head
    character(len=:), allocatable :: path, base
    integer :: version, k
    avail = -1.0_wp
    kb = file_key_value('/proc/meminfo', 'MemAvailable:')
    if (kb < 0.0_wp) return
    avail = 1024.0_wp*kb
    call own_cgroup(version, path)
    if (version == 0) return
    base = merge('/sys/fs/cgroup       ', '/sys/fs/cgroup/memory', version == 2)
    base = trim(base)
    do
      head = cgroup_headroom(base//path, version)
      if (head >= 0.0_wp) avail = min(avail, head)
      if (len(path) == 0) exit
      k = index(path, '/', back=.true.)
      path = path(1:max(k - 1, 0))
    end do
  end function node_available_bytes

  !> The memory cgroup of this process from /proc/self/cgroup: version 2 (the '0::' line) or 1
  !> (the line whose controllers include memory), and its path without a trailing '/';
  !> version 0 where there is none.
  subroutine own_cgroup(version, path)
    integer, intent(out) :: version
    character(len=:), allocatable, intent(out) :: path
    character(len=1024) :: line
    integer :: u, ios, a, b
    version = 0
    path = ''
    open(newunit=u, file='/proc/self/cgroup', action='read', status='old', iostat=ios)
    if (ios /= 0) return
    do
      read(u, '(a)', iostat=ios) line
      if (ios /= 0) exit
      a = index(line, ':')
      b = index(line, ':', back=.true.)
      if (a == 0 .or. b <= a) cycle
      if (line(1:a) == '0:' .and. b == a + 1) then
        if (version == 0) then
          version = 2
          path = trim(line(b + 1:))
        end if
      else if (index(','//line(a + 1:b - 1)//',', ',memory,') > 0) then
        version = 1
        path = trim(line(b + 1:))
        exit
      end if
    end do
    close(u)
    if (len(path) > 0) then
      if (path(len(path):len(path)) == '/') path = path(1:len(path) - 1)
    end if
  end subroutine own_cgroup

  !> Limit less unreclaimable usage of the memory cgroup in folder dir; -1 when it has no
  !> limit or its files cannot be read.
  function cgroup_headroom(dir, version) result(head)
    character(len=*), intent(in) :: dir
    integer, intent(in) :: version
    real(wp) :: head, limit, usage, inactive
    head = -1.0_wp
    if (version == 2) then
      limit = file_number(dir//'/memory.max')
      usage = file_number(dir//'/memory.current')
      inactive = file_key_value(dir//'/memory.stat', 'inactive_file')
    else
      limit = file_number(dir//'/memory.limit_in_bytes')
      usage = file_number(dir//'/memory.usage_in_bytes')
      inactive = file_key_value(dir//'/memory.stat', 'total_inactive_file')
    end if
    ! no limit: 'max' (v2, read as -1) or a number near 2^63 (v1)
    if (limit < 0.0_wp .or. limit >= 2.0_wp**62) return
    head = limit
    if (usage >= 0.0_wp) head = limit - max(usage - max(inactive, 0.0_wp), 0.0_wp)
    head = max(head, 0.0_wp)
  end function cgroup_headroom

  !> The number a file holds on its first line; -1 when it cannot be read or holds no number.
  function file_number(path) result(x)
    character(len=*), intent(in) :: path
    real(wp) :: x
    character(len=128) :: line
    integer :: u, ios
    x = -1.0_wp
    open(newunit=u, file=path, action='read', status='old', iostat=ios)
    if (ios /= 0) return
    read(u, '(a)', iostat=ios) line
    close(u)
    if (ios /= 0) return
    read(line, *, iostat=ios) x
    if (ios /= 0) x = -1.0_wp
  end function file_number

  !> The number after key on the line that starts with key (e.g. 'MemAvailable:' in
  !> /proc/meminfo); -1 when there is none.
  function file_key_value(path, key) result(x)
    character(len=*), intent(in) :: path, key
    real(wp) :: x
    character(len=256) :: line
    integer :: u, ios
    x = -1.0_wp
    open(newunit=u, file=path, action='read', status='old', iostat=ios)
    if (ios /= 0) return
    do
      read(u, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:len(key)) == key .and. line(len(key) + 1:len(key) + 1) == ' ') then
        read(line(len(key) + 1:), *, iostat=ios) x
        if (ios /= 0) x = -1.0_wp
        exit
      end if
    end do
    close(u)
  end function file_key_value

  !> Collective over comm: stat = 1 with msg on every rank when the ranks sharing a node need
  !> more (set-up or run, whichever is larger, summed over them) than that node has available;
  !> label names the input ('&geometry: nx, ny = ...'). A node whose available memory cannot
  !> be read is not checked. info (rank 0's node) is for the log.
  subroutine memory_check(comm, need, label, stat, msg, info)
    type(MPI_Comm), intent(in) :: comm
    type(memory_need_t), intent(in) :: need
    character(len=*), intent(in) :: label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg, info
    type(MPI_Comm) :: node
    integer :: rank, n_ranks, node_rank, node_size
    real(wp) :: node_need, avail, worst(2), facts(3)
    character(len=:), allocatable :: where

    stat = 0
    msg = ''
    call MPI_Comm_rank(comm, rank)
    call MPI_Comm_size(comm, n_ranks)
    call MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, rank, MPI_INFO_NULL, node)
    call MPI_Comm_rank(node, node_rank)
    node_need = need%peak()
    call MPI_Allreduce(MPI_IN_PLACE, node_need, 1, mpi_wp(), MPI_SUM, node)
    avail = -1.0_wp
    if (node_rank == 0) avail = node_available_bytes()
    call MPI_Bcast(avail, 1, mpi_wp(), 0, node)
    ! facts of this node: available bytes, ranks, whether rank 0 is among them
    call MPI_Comm_size(node, node_size)
    facts = [avail, real(node_size, wp), merge(1.0_wp, 0.0_wp, rank == 0)]
    call MPI_Allreduce(MPI_IN_PLACE, facts(3), 1, mpi_wp(), MPI_SUM, node)
    call MPI_Comm_free(node)
    info = 'memory: about '//bytes_text(need%peak())//' needed on each of the '// &
           itoa(n_ranks)//' rank(s) ('//need%what()//')'
    if (avail >= 0.0_wp) then
      info = info//'; '//bytes_text(avail)//' available on this node for its '// &
             itoa(nint(facts(2)))//' rank(s)'
    else
      info = info//'; the available memory cannot be read here (not checked)'
    end if
    ! the node that lacks the most: ratio need / available, and its rank
    worst = [0.0_wp, real(rank, wp)]
    if (avail > 0.0_wp) worst(1) = node_need/avail
    if (avail == 0.0_wp) worst(1) = huge(1.0_wp)
    call MPI_Allreduce(MPI_IN_PLACE, worst, 1, MPI_2DOUBLE_PRECISION, MPI_MAXLOC, comm)
    if (worst(1) <= 1.0_wp) return
    call MPI_Bcast(facts, 3, mpi_wp(), int(worst(2)), comm)
    stat = 1
    if (n_ranks == 1) then
      msg = label//' needs about '//bytes_text(need%peak())//' ('//need%what()//')'
    else
      msg = label//' needs about '//bytes_text(need%peak())//' on each of the '// &
            itoa(n_ranks)//' ranks ('//need%what()//')'
    end if
    where = 'a node'
    if (facts(3) > 0.0_wp) where = 'this node'
    if (nint(facts(2)) > 1) then
      msg = msg//', but '//bytes_text(facts(1)/facts(2))//' are available to each of the '// &
            itoa(nint(facts(2)))//' ranks on '//where//' ('//bytes_text(facts(1))// &
            ' in all: MemAvailable, capped by the cgroup limit)'
    else
      msg = msg//', but '//bytes_text(facts(1))//' are available on '//where// &
            ' (MemAvailable, capped by the cgroup limit)'
    end if
    msg = msg//'; use more nodes, fewer ranks a node, or a coarser grid'
  end subroutine memory_check

  !> Bytes as text with a binary unit: '512 MiB', '20.1 GiB', '280 GiB'.
  pure function bytes_text(b) result(s)
    real(wp), intent(in) :: b
    character(len=:), allocatable :: s
    character(len=*), parameter :: units(5) = ['B  ', 'KiB', 'MiB', 'GiB', 'TiB']
    real(wp) :: x
    integer :: k
    x = max(b, 0.0_wp)
    k = 1
    do while (x >= 1024.0_wp .and. k < size(units))
      x = x/1024.0_wp
      k = k + 1
    end do
    s = approx_text(x)//' '//trim(units(k))
  end function bytes_text

  !> A positive number to 3 significant digits at most: '20.1', '280', '3.1e8'.
  pure function approx_text(x) result(s)
    real(wp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=32) :: b
    integer :: e
    if (x < 1.0e-3_wp) then
      s = '0'
    else if (x < 9.995_wp) then
      write(b, '(f0.2)') x
      s = trim(adjustl(b))
    else if (x < 99.95_wp) then
      write(b, '(f0.1)') x
      s = trim(adjustl(b))
    else if (x < 1.0e4_wp) then
      write(b, '(i0)') nint(x)
      s = trim(b)
    else
      e = floor(log10(x))
      write(b, '(f0.1,a,i0)') x/10.0_wp**e, 'e', e
      s = trim(adjustl(b))
      if (b(1:2) == '10') then
        write(b, '(a,i0)') '1.0e', e + 1
        s = trim(b)
      end if
    end if
  end function approx_text
end module iem_memory
